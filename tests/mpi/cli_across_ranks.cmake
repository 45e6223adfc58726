# The commands across ranks against the serial commands on the same files (docs/mpi.md, "The
# command-line tool"):
#  - `mpiexec -n NP rpyfmm mobility --method direct`: the distributed direct operator is the serial
#    one bit for bit, so the two .npy files must be identical byte for byte;
#  - `mpiexec -n NP rpyfmm mobility --method fmm --tolerance E`: DistributedFmmRpy meets FmmRpy's
#    contract (relative l2 error of U at most E), so U must lie within E of the serial direct file
#    and within 2E of the serial FMM's (laplace_agree);
#  - `mpiexec -n NP rpyfmm mobility --torques T` or `--angular` (N,6): direct the serial file byte
#    for byte; fmm within E of the serial direct file, U and W each; --angular the same file as
#    zero torques; --method pse --box L with --torques or --angular as below;
#  - `mpiexec -n NP rpyfmm sample --operator fmm`: Lanczos on DistributedFmmRpy, within 1e-5 of the
#    serial direct sampler's file (see below), with the products' MPI time in --json;
#  - `mpiexec -n NP rpyfmm sample --operator direct`: the distributed Lanczos sampler is the serial
#    one bit for bit too (its inner products are the serial ones), on the noise drawn by seed and
#    on noise read from a file: identical files;
#  - `mpiexec -n NP rpyfmm sample --method chebyshev`: the serial Chebyshev sampler bit for bit,
#    identical files; with `--preconditioner block` (the serial blocks of the whole set) too;
#  - `mpiexec -n NP rpyfmm sample --angular` (N,6): direct the serial file byte for byte (noise by
#    seed and from an (N,6) file), fmm within 1e-5 of the serial direct file, pse within 1e-12 of
#    the serial file with double grids, w_t and w_r each;
#  - `mpiexec -n NP rpyfmm laplace --tolerance E`: DistributedLaplaceFmm meets the serial FMM's
#    contract (relative l2 error of each output at most E), not its bits, so the output must lie
#    within E of the serial direct sum and within 2E of the serial FMM (both within E of the exact
#    sums), output by output and density by density (laplace_agree, -DAGREE=...);
#  - `mpiexec -n NP rpyfmm laplace --direct`: every rank sums all sources at its targets in the
#    serial order, so the files are identical byte for byte;
#  - `mpiexec -n NP rpyfmm rigid --method direct`: within 1e-12 of the serial file (velocities and
#    bead forces), the inner products summed in another order; `--method fmm --tolerance 1e-8`
#    within 1e-7 of the serial direct solve (see below); `--method pse --box L` within 1e-9 of the
#    serial file with double wave grids (see below); `--wave-precision single` refuses;
#  - `mpiexec -n NP rpyfmm rigid-bd --method direct|fmm|pse`: the serial trajectory to round-off
#    (direct), to the FMMs' tolerance, or with `--method pse --box L` within 1e-6 of the serial file
#    with double wave grids (see below), a restart byte for byte; with `--pair wca` the same
#    bounds; `--method pse --wave-precision single` refuses;
#  - `mpiexec -n NP rpyfmm mobility --method pse --box L` (also with --torques or --angular, U and W
#    each) and `sample --operator pse --box L`: DistributedPseRpy is the serial PseRpy with double
#    wave grids to round-off, so within 1e-12 relative of that serial output.
# --json must report the ranks and the communication time per stage. Run by ctest as
#   cmake -DRPYFMM=... -DMPIEXEC=... -DNP=... "-DMPI_FLAGS=..." -DWORK=... -P cli_across_ranks.cmake
cmake_minimum_required(VERSION 3.20)
foreach(var RPYFMM MPIEXEC NP AGREE WORK)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "cli_across_ranks.cmake: -D${var}=... is required")
  endif()
endforeach()
separate_arguments(flags UNIX_COMMAND "${MPI_FLAGS}")
file(REMOVE_RECURSE "${WORK}")
file(MAKE_DIRECTORY "${WORK}")

# 701 particles (not a multiple of NP, shares straddle DirectRpy's 256-source blocks), written as
# text from a linear congruential generator: positions in [0, 40), radii in [0.5, 1.5) (overlaps
# included), forces in [-1, 1].
set(seed 12345)
macro(next_value modulus out)
  math(EXPR seed "(${seed} * 1103515245 + 12345) % 2147483648")
  math(EXPR ${out} "${seed} % ${modulus}")
endmacro()
macro(decimal value out)  # value / 1000 with three decimals
  math(EXPR _int "${value} / 1000")
  math(EXPR _frac "${value} % 1000 + 1000")
  string(SUBSTRING "${_frac}" 1 3 _frac)
  set(${out} "${_int}.${_frac}")
endmacro()
macro(signed_decimal out)  # the next value in [-1, 1] with three decimals
  next_value(2001 _v)
  if(_v LESS 1000)
    math(EXPR _v "1000 - ${_v}")
    decimal(${_v} _d)
    set(${out} "-${_d}")
  else()
    math(EXPR _v "${_v} - 1000")
    decimal(${_v} ${out})
  endif()
endmacro()
set(x "")
set(f "")
set(a "")
set(q2 "")
foreach(i RANGE 700)
  set(row "")
  set(frow "")
  foreach(c 0 1 2)
    next_value(40000 v)
    decimal(${v} d)
    string(APPEND row " ${d}")
    signed_decimal(d)
    string(APPEND frow " ${d}")
  endforeach()
  next_value(1000 v)
  math(EXPR v "${v} + 500")
  decimal(${v} d)
  string(APPEND x "${row}\n")
  string(APPEND f "${frow}\n")
  string(APPEND a "${d}\n")
  string(APPEND q2 " ${d}")
endforeach()
# Two densities for laplace: the radii's values and their negatives.
string(REPLACE " " " -" q2neg "${q2}")
string(APPEND q2 "\n${q2neg}\n")
file(WRITE "${WORK}/x.txt" "${x}")
file(WRITE "${WORK}/f.txt" "${f}")
file(WRITE "${WORK}/a.txt" "${a}")
file(WRITE "${WORK}/q2.txt" "${q2}")
# Torques in [-1, 1] drawn after the particles, the same torques but the last row (a wrong row
# count), and zero torques; and noise of six columns for sample --angular, each particle's forces
# then its torques (z_t then z_r).
string(REGEX REPLACE "\n$" "" f_rows "${f}")
string(REPLACE "\n" ";" f_rows "${f_rows}")
set(t "")
set(z6 "")
foreach(i RANGE 700)
  set(trow "")
  foreach(c 0 1 2)
    signed_decimal(d)
    string(APPEND trow " ${d}")
  endforeach()
  list(GET f_rows ${i} frow)
  string(APPEND z6 "${frow}${trow}\n")
  if(i EQUAL 700)
    set(t_short "${t}")
  endif()
  string(APPEND t "${trow}\n")
endforeach()
string(REPEAT "0 0 0\n" 701 t0)
file(WRITE "${WORK}/t.txt" "${t}")
file(WRITE "${WORK}/t_short.txt" "${t_short}")
file(WRITE "${WORK}/t0.txt" "${t0}")
file(WRITE "${WORK}/z6.txt" "${z6}")

# The serial command `args` writing ${WORK}/<out>.npy, and the same across NP ranks with --json
# writing ${WORK}/<name>_mpi.npy, its JSON line in the caller's `json`.
function(run_serial name out)
  execute_process(COMMAND "${RPYFMM}" ${ARGN} --out "${WORK}/${out}.npy" RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${name}: serial rpyfmm ${ARGN} failed (${rc}): ${err}")
  endif()
endfunction()
function(run_across name)
  execute_process(COMMAND "${MPIEXEC}" -n ${NP} ${flags} "${RPYFMM}" ${ARGN} --out "${WORK}/${name}_mpi.npy" --json
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${name}: mpiexec -n ${NP} rpyfmm ${ARGN} failed (${rc}): ${err}")
  endif()
  string(REGEX MATCHALL "\"command\"" lines "${out}")
  list(LENGTH lines count)
  if(NOT count EQUAL 1 OR NOT out MATCHES "\"ranks\":${NP},")
    message(FATAL_ERROR "${name}: --json is not one line with \"ranks\":${NP}: ${out}")
  endif()
  set(json "${out}" PARENT_SCOPE)
endfunction()
# The serial command and its run across ranks write the same bytes.
function(run_identical name)
  run_serial(${name} ${name}_serial ${ARGN})
  run_across(${name} ${ARGN})
  execute_process(COMMAND "${CMAKE_COMMAND}" -E compare_files "${WORK}/${name}_serial.npy" "${WORK}/${name}_mpi.npy"
                  RESULT_VARIABLE differ)
  if(NOT differ EQUAL 0)
    message(FATAL_ERROR "${name}: the output of ${NP} ranks differs from the serial output")
  endif()
  set(json "${json}" PARENT_SCOPE)
endfunction()

# mobility with a common radius and with per-particle radii.
foreach(radius_args "--radius;1.1" "--radii;${WORK}/a.txt")
  list(GET radius_args 0 name)
  string(REPLACE "-" "" name "mobility${name}")
  run_identical(${name} mobility --positions "${WORK}/x.txt" --forces "${WORK}/f.txt" ${radius_args} --viscosity 0.7
                --method direct)
  if(NOT json MATCHES "\"communication_seconds\":{\"apply\"")
    message(FATAL_ERROR "${name}: --json lacks communication_seconds: ${json}")
  endif()
endforeach()

# sample: with the noise of (seed, step) and with the forces file read as noise.
foreach(noise_args "--seed;5;--step;3" "--noise;${WORK}/f.txt")
  list(GET noise_args 0 name)
  string(REPLACE "-" "" name "sample${name}")
  run_identical(${name} sample --positions "${WORK}/x.txt" --radii "${WORK}/a.txt" --operator direct --method lanczos
                --sqrt-tolerance 1e-6 --viscosity 0.7 ${noise_args})
  if(NOT json MATCHES "\"inner_products\":")
    message(FATAL_ERROR "${name}: --json lacks the inner products' time: ${json}")
  endif()
endforeach()

# Outputs that agree to a tolerance contract (laplace_agree).
function(agree name a b bound)
  execute_process(COMMAND "${AGREE}" "${a}" "${b}" ${bound} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${name}: ${NP} ranks against ${b} beyond ${bound} (${rc}): ${out}${err}")
  endif()
endfunction()

# mobility with the FMM at 1e-6 (per-particle radii, overlapping pairs among them), against the
# serial direct and FMM files.
set(fmm_common mobility --positions "${WORK}/x.txt" --forces "${WORK}/f.txt" --radii "${WORK}/a.txt" --viscosity 0.7)
run_serial(mobility_fmm mobility_fmm_direct ${fmm_common} --method direct)
run_serial(mobility_fmm mobility_fmm_serial ${fmm_common} --method fmm --tolerance 1e-6)
run_across(mobility_fmm ${fmm_common} --method fmm --tolerance 1e-6)
if(NOT json MATCHES "\"method\":\"fmm\"" OR NOT json MATCHES "\"communication_seconds\":{\"apply\"")
  message(FATAL_ERROR "mobility_fmm: --json lacks the method or communication_seconds: ${json}")
endif()
agree(mobility_fmm "${WORK}/mobility_fmm_mpi.npy" "${WORK}/mobility_fmm_direct.npy" 1e-6)
agree(mobility_fmm "${WORK}/mobility_fmm_mpi.npy" "${WORK}/mobility_fmm_serial.npy" 2e-6)

# mobility with rotation, (N,6) rows Ux Uy Uz Wx Wy Wz. direct: DistributedDirectRpy's product with
# rotation is DirectRpy's bit for bit on every partition (rpyfmm/mpi/direct_operator.hpp), so the
# files are identical. fmm --tolerance E: DistributedFmmRpy's contract with rotation, U and W each
# within E of the exact product (the serial direct file).
set(rotation_common mobility --positions "${WORK}/x.txt" --forces "${WORK}/f.txt" --radii "${WORK}/a.txt"
                    --viscosity 0.7 --torques "${WORK}/t.txt")
run_identical(torques_direct ${rotation_common} --method direct)
if(NOT json MATCHES "\"method\":\"direct\"" OR NOT json MATCHES "\"communication_seconds\":{\"apply\"")
  message(FATAL_ERROR "torques_direct: --json lacks the method or communication_seconds: ${json}")
endif()
run_across(torques_fmm ${rotation_common} --method fmm --tolerance 1e-6)
if(NOT json MATCHES "\"method\":\"fmm\"" OR NOT json MATCHES "\"communication_seconds\":{\"apply\"")
  message(FATAL_ERROR "torques_fmm: --json lacks the method or communication_seconds: ${json}")
endif()
agree(torques_fmm "${WORK}/torques_fmm_mpi.npy" "${WORK}/torques_direct_serial.npy" 1e-6)
# --angular: the torques are zero, the same file as --torques with zeros and as the serial --angular
# (with a common radius).
set(angular_common mobility --positions "${WORK}/x.txt" --forces "${WORK}/f.txt" --radius 1.1 --viscosity 0.7
                   --method direct)
run_serial(angular angular_serial ${angular_common} --angular)
run_across(angular ${angular_common} --angular)
run_across(angular_zeros ${angular_common} --torques "${WORK}/t0.txt")
execute_process(COMMAND "${CMAKE_COMMAND}" -E compare_files "${WORK}/angular_mpi.npy" "${WORK}/angular_zeros_mpi.npy"
                RESULT_VARIABLE differ)
if(NOT differ EQUAL 0)
  message(FATAL_ERROR "angular: --angular on ${NP} ranks differs from --torques with zero torques")
endif()
execute_process(COMMAND "${CMAKE_COMMAND}" -E compare_files "${WORK}/angular_mpi.npy" "${WORK}/angular_serial.npy"
                RESULT_VARIABLE differ)
if(NOT differ EQUAL 0)
  message(FATAL_ERROR "angular: --angular on ${NP} ranks differs from the serial --angular output")
endif()

# sample with Chebyshev: the distributed Chebyshev sampler is the serial one bit for bit (the bound
# estimate's inner products are the serial ones, the recurrence elementwise): identical files.
run_identical(samplechebyshev sample --positions "${WORK}/x.txt" --radii "${WORK}/a.txt" --operator direct
              --method chebyshev --sqrt-tolerance 1e-6 --viscosity 0.7 --seed 5 --step 3)
if(NOT json MATCHES "\"method\":\"chebyshev\"" OR NOT json MATCHES "\"lambda_min\":")
  message(FATAL_ERROR "samplechebyshev: --json lacks the method or the eigenvalue bounds: ${json}")
endif()
# sample with the block preconditioner: the blocks are the serial command's of the whole set on any
# partition, each factored by one rank and applied there (docs/mpi.md), so the file is the serial
# command's byte for byte and --json reports the blocks.
run_identical(sampleblock sample --positions "${WORK}/x.txt" --radii "${WORK}/a.txt" --operator direct --method lanczos
           --preconditioner block --sqrt-tolerance 1e-6 --viscosity 0.7 --seed 5 --step 3)
if(NOT json MATCHES "\"preconditioner_blocks\":[1-9]" OR NOT EXISTS "${WORK}/sampleblock_mpi.npy")
  message(FATAL_ERROR "sampleblock: no output or no preconditioner blocks in --json: ${json}")
endif()
# The blocks' gather and exchanges are among the communication seconds, above zero: on more than
# one rank the gather receives the other ranks' positions and G moves the rows of shared blocks.
if(NOT json MATCHES "\"blocks\":(0\\.0*[1-9]|[1-9])")
  message(FATAL_ERROR "sampleblock: --json lacks the blocks' communication seconds or they are 0: ${json}")
endif()

# sample with the FMM operator at 1e-9 and Lanczos at 1e-6, against the serial direct sampler's
# file: the operators differ by at most 1e-9 relative, far below the iteration's tolerance, and each
# iteration stops within its tolerance of its own operator's root, so the two lie within 1e-5.
set(sample_common sample --positions "${WORK}/x.txt" --radii "${WORK}/a.txt" --method lanczos --sqrt-tolerance 1e-6
                  --viscosity 0.7 --seed 5 --step 3)
run_serial(sample_fmm sample_fmm_direct ${sample_common} --operator direct)
run_across(sample_fmm ${sample_common} --operator fmm --tolerance 1e-9)
# DistributedFmmRpy sums its products' MPI time (communication_seconds.products).
if(NOT json MATCHES "\"operator\":\"fmm\"" OR NOT json MATCHES "\"inner_products\":"
   OR NOT json MATCHES "\"communication_seconds\":{[^}]*\"products\":[0-9]")
  message(FATAL_ERROR "sample_fmm: --json lacks the operator, the inner products' or the products' time: ${json}")
endif()
agree(sample_fmm "${WORK}/sample_fmm_mpi.npy" "${WORK}/sample_fmm_direct.npy" 1e-5)

# sample --angular, (N,6) rows w_t then w_r of the grand mobility. direct: the distributed
# sampler with rotation is the serial DirectRpy::apply_sqrt_rotation bit for bit (its inner
# products of [x_t; x_r] summed in the serial order; rpyfmm/mpi/sqrt.hpp), with the noise of
# (seed, step) (z_r from BD's rotational stream on every rank's share) and with (N,6) noise read
# from a file: identical files. fmm at 1e-9 against the serial direct file as above, w_t and w_r
# each within 1e-5.
foreach(noise_args "--seed;5;--step;3" "--noise;${WORK}/z6.txt")
  list(GET noise_args 0 name)
  string(REPLACE "-" "" name "sampleangular${name}")
  run_identical(${name} sample --positions "${WORK}/x.txt" --radii "${WORK}/a.txt" --method lanczos
                --sqrt-tolerance 1e-6 --viscosity 0.7 --operator direct --angular ${noise_args})
  if(NOT json MATCHES "\"angular\":true")
    message(FATAL_ERROR "${name}: --json does not report angular: ${json}")
  endif()
endforeach()
run_serial(sample_angular_fmm sample_angular_fmm_direct ${sample_common} --operator direct --angular)
run_across(sample_angular_fmm ${sample_common} --operator fmm --tolerance 1e-9 --angular)
agree(sample_angular_fmm "${WORK}/sample_angular_fmm_mpi.npy" "${WORK}/sample_angular_fmm_direct.npy" 1e-5)

# laplace with the FMM: at the sources (one density) and at separate targets (two densities).
function(run_laplace name tolerance twice)
  set(common laplace --sources "${WORK}/x.txt" ${ARGN})
  run_serial(${name} ${name}_direct ${common} --direct)
  run_serial(${name} ${name}_fmm ${common} --tolerance ${tolerance})
  run_across(${name} ${common} --tolerance ${tolerance})
  if(NOT json MATCHES "\"communication_seconds\":{[^}]*\"evaluate\":[^}]*\"plan\":"
     OR NOT json MATCHES "\"communication_bytes\":{\"evaluate\":[0-9]")
    message(FATAL_ERROR "${name}: --json lacks the plan's and evaluation's communication: ${json}")
  endif()
  agree(${name} "${WORK}/${name}_mpi.npy" "${WORK}/${name}_direct.npy" ${tolerance})
  agree(${name} "${WORK}/${name}_mpi.npy" "${WORK}/${name}_fmm.npy" ${twice})
endfunction()
run_laplace(laplace_sources 1e-6 2e-6 --charges "${WORK}/a.txt")
run_laplace(laplace_targets 1e-3 2e-3 --charges "${WORK}/q2.txt" --targets "${WORK}/f.txt")
# laplace --direct: every rank sums all sources at its share of the targets, each target alone and in
# the serial order (fmm::laplace_direct), so the file is the serial command's byte for byte: at the
# sources (one density, the self pairs skipped) and at separate targets (two densities).
run_identical(laplace_direct_sources laplace --sources "${WORK}/x.txt" --charges "${WORK}/a.txt" --direct)
if(NOT json MATCHES "\"method\":\"direct\"" OR json MATCHES "\"tolerance\"")
  message(FATAL_ERROR "laplace_direct_sources: --json does not name the method direct alone: ${json}")
endif()
run_identical(laplace_direct_targets laplace --sources "${WORK}/x.txt" --charges "${WORK}/q2.txt" --targets
              "${WORK}/f.txt" --direct)

# mobility and sample (the split sampler, noise by seed) with PSE in the box [0, 40)^3:
# DistributedPseRpy is the serial PseRpy with double wave grids to round-off (the same terms summed
# in another order; tests/mpi/test_distributed_pse.cpp), so within 1e-12 relative of the serial
# command with --wave-precision double; --json names `pattern`.
function(run_pse name pattern)
  run_serial(${name} ${name}_serial ${ARGN} --wave-precision double)
  run_across(${name} ${ARGN})
  if(NOT json MATCHES "${pattern}")
    message(FATAL_ERROR "${name}: --json lacks ${pattern}: ${json}")
  endif()
  agree(${name} "${WORK}/${name}_mpi.npy" "${WORK}/${name}_serial.npy" 1e-12)
endfunction()
run_pse(mobility_pse "\"method\":\"pse\"" mobility --positions "${WORK}/x.txt" --forces "${WORK}/f.txt" --radius 1.1
        --viscosity 0.7 --method pse --box 40 --tolerance 1e-4)
# With rotation, (N,6): DistributedPseRpy's grand product is PseRpy's to round-off as well (the
# same terms in another order, test_distributed_pse.cpp), U and W each within 1e-12.
run_pse(torques_pse "\"method\":\"pse\"" mobility --positions "${WORK}/x.txt" --forces "${WORK}/f.txt" --radius 1.1
        --viscosity 0.7 --method pse --box 40 --tolerance 1e-4 --torques "${WORK}/t.txt")
run_pse(angular_pse "\"method\":\"pse\"" mobility --positions "${WORK}/x.txt" --forces "${WORK}/f.txt" --radius 1.1
        --viscosity 0.7 --method pse --box 40 --tolerance 1e-4 --angular)
run_pse(sample_pse "\"operator\":\"pse\",\"method\":\"split\"" sample --positions "${WORK}/x.txt" --radius 1.1
        --viscosity 0.7 --operator pse --box 40 --tolerance 1e-4 --seed 5 --step 3)
# The split sampler of the grand mobility (DistributedPseRpy::apply_sqrt_rotation, PseRpy's to
# round-off: test_distributed_pse.cpp), w_t and w_r each within 1e-12.
run_pse(sample_angular_pse "\"angular\":true" sample --positions "${WORK}/x.txt" --radius 1.1 --viscosity 0.7
        --operator pse --box 40 --tolerance 1e-4 --seed 5 --step 3 --angular)

# A bad input read by rank 0 fails every rank: exit status 2, one error line (printed by rank 0),
# no output.
include("${CMAKE_CURRENT_LIST_DIR}/expect_one_error.cmake")
set(never "${WORK}/never.npy")
expect_one_error("a missing input" "missing.txt" ${never} "${RPYFMM}" mobility --positions "${WORK}/missing.txt"
                 --forces "${WORK}/f.txt" --radius 1 --out ${never})
# So does a torques file with a row too few: the serial command's message.
expect_one_error("torques with 700 rows" "torques: has 700 rows, expected 701" ${never} "${RPYFMM}" mobility
                 --positions "${WORK}/x.txt" --forces "${WORK}/f.txt" --radius 1 --torques "${WORK}/t_short.txt"
                 --out ${never})
# So does noise of three columns with sample --angular.
expect_one_error("sample --angular with (N,3) noise" "noise: with --angular must have shape \\(701,6\\)" ${never}
                 "${RPYFMM}" sample --positions "${WORK}/x.txt" --radius 1 --noise "${WORK}/f.txt" --angular
                 --out ${never})
# So does a missing input of laplace.
expect_one_error("laplace with a missing input" "missing.txt" ${never} "${RPYFMM}" laplace --sources "${WORK}/x.txt"
                 --charges "${WORK}/q2.txt" --targets "${WORK}/missing.txt" --tolerance 1e-6 --out ${never})
# rigid: 27 bodies on a lattice of spacing 4 (cubes of 8 beads and tetrahedra of 4, side 2, beads
# of radius 0.5, every coordinate shifted by a jitter in [0, 0.1)), forces and torques in [-1, 1];
# the ranks own contiguous runs of whole bodies balanced by bead count. direct: DistributedRigidBodies
# with DistributedDirectRpy differs from the serial solver only by the order of the inner products'
# sums, so within 1e-12 of the serial file (velocities and bead forces; the bound of
# tests/mpi/test_distributed_rigid.cpp). fmm at 1e-8, GMRES to 1e-8: within
# 1e-7 of the serial direct solve to 1e-12 (as that test's bound).
set(bodies "")
set(body_sizes "")
set(body_forces "")
set(bodies_wrapped "")  # the same beads wrapped into the box of side 11 (rigid-bd --method pse)
set(cube "-1,-1,-1;-1,-1,1;-1,1,-1;-1,1,1;1,-1,-1;1,-1,1;1,1,-1;1,1,1")
set(tetrahedron "1,1,1;1,-1,-1;-1,1,-1;-1,-1,1")
foreach(k RANGE 26)
  math(EXPR centre_x "4 * (${k} % 3) + 2")
  math(EXPR centre_y "4 * (${k} / 3 % 3) + 2")
  math(EXPR centre_z "4 * (${k} / 9) + 2")
  math(EXPR odd "${k} % 2")
  if(odd)
    set(corners "${tetrahedron}")
  else()
    set(corners "${cube}")
  endif()
  list(LENGTH corners size)
  string(APPEND body_sizes "${size}\n")
  foreach(corner ${corners})
    string(REPLACE "," ";" corner "${corner}")
    set(row "")
    set(wrapped_row "")
    foreach(c 0 1 2)
      list(GET corner ${c} d)
      set(centre ${centre_x})
      if(c EQUAL 1)
        set(centre ${centre_y})
      elseif(c EQUAL 2)
        set(centre ${centre_z})
      endif()
      math(EXPR v "${centre} + ${d}")
      next_value(100 jitter)
      decimal(${jitter} jitter)
      string(SUBSTRING "${jitter}" 2 3 jitter)
      string(APPEND row " ${v}.${jitter}")
      math(EXPR wrapped "${v} % 11")
      string(APPEND wrapped_row " ${wrapped}.${jitter}")
    endforeach()
    string(APPEND bodies "${row}\n")
    string(APPEND bodies_wrapped "${wrapped_row}\n")
  endforeach()
  set(row "")
  foreach(c RANGE 5)
    signed_decimal(d)
    string(APPEND row " ${d}")
  endforeach()
  string(APPEND body_forces "${row}\n")
endforeach()
file(WRITE "${WORK}/bodies.txt" "${bodies}")
file(WRITE "${WORK}/bodies_wrapped.txt" "${bodies_wrapped}")
file(WRITE "${WORK}/body_sizes.txt" "${body_sizes}")
file(WRITE "${WORK}/body_forces.txt" "${body_forces}")
set(rigid_common rigid --positions "${WORK}/bodies.txt" --radius 0.5 --body-sizes "${WORK}/body_sizes.txt" --forces
                 "${WORK}/body_forces.txt" --viscosity 0.7)
run_serial(rigid rigid_serial ${rigid_common} --method direct --solver-tolerance 1e-10 --bead-forces
           "${WORK}/rigid_beads_serial.npy")
run_across(rigid ${rigid_common} --method direct --solver-tolerance 1e-10 --bead-forces "${WORK}/rigid_beads_mpi.npy")
if(NOT json MATCHES "\"iterations\":[1-9]" OR NOT json MATCHES "\"method\":\"direct\"" OR NOT json MATCHES
                                                                                   "\"communication_seconds\":{")
  message(FATAL_ERROR "rigid: --json lacks the iterations, the method or communication_seconds: ${json}")
endif()
agree(rigid "${WORK}/rigid_mpi.npy" "${WORK}/rigid_serial.npy" 1e-12)
agree(rigid "${WORK}/rigid_beads_mpi.npy" "${WORK}/rigid_beads_serial.npy" 1e-12)
run_serial(rigid_fmm rigid_fmm_direct ${rigid_common} --method direct --solver-tolerance 1e-12)
run_across(rigid_fmm ${rigid_common} --method fmm --tolerance 1e-8 --solver-tolerance 1e-8)
agree(rigid_fmm "${WORK}/rigid_fmm_mpi.npy" "${WORK}/rigid_fmm_direct.npy" 1e-7)
# pse in the periodic box of side 11: the bodies centred at 10 reach 11.1 and are wrapped, so they
# straddle the faces. DistributedRigidBodies with DistributedPseRpy (the serial PseRpy with double
# wave grids to round-off) and GMRES to 1e-10: within 1e-9 of the serial file with double grids,
# velocities and bead forces (the bound of tests/mpi/test_distributed_rigid_periodic.cpp).
set(rigid_pse ${rigid_common} --method pse --box 11 --solver-tolerance 1e-10)
run_serial(rigid_pse rigid_pse_serial ${rigid_pse} --wave-precision double --bead-forces
           "${WORK}/rigid_pse_beads_serial.npy")
run_across(rigid_pse ${rigid_pse} --bead-forces "${WORK}/rigid_pse_beads_mpi.npy")
if(NOT json MATCHES "\"iterations\":[1-9]" OR NOT json MATCHES "\"method\":\"pse\"")
  message(FATAL_ERROR "rigid_pse: --json lacks the iterations or the method: ${json}")
endif()
agree(rigid_pse "${WORK}/rigid_pse_mpi.npy" "${WORK}/rigid_pse_serial.npy" 1e-9)
agree(rigid_pse "${WORK}/rigid_pse_beads_mpi.npy" "${WORK}/rigid_pse_beads_serial.npy" 1e-9)

# rigid-bd on the same bodies: 4 steps at kT 1 with the RFD drift, under gravity and a torque.
# Across the ranks the bead noise is the principal root (--sqrt-preconditioner auto is none there),
# the serial sampler's bits, so with --method direct the trajectory differs from the serial
# command's with --sqrt-preconditioner none only by the order of GMRES's inner-product sums: within
# 1e-11 per frame (positions and orientations, relative; the bound of
# tests/mpi/test_distributed_rigid_bd.cpp), and so the final beads. A restart from the state after
# step 2 on NP ranks ends at the beads of the 4-step run, byte for byte. --method fmm at 1e-8
# against the serial FMM at 1e-8: the two FMMs' products differ by up to their tolerances
# (different trees), so the trajectories by the solve's error at 1e-8 carried through 4 steps
# and the RFD's 1 / delta = 1e3 on the difference of two solves: within 1e-5. Measured at 2 and 3
# ranks (shared 2-core AMD EPYC, AVX-512, 2026-12-07): direct at most 7.4e-16 per frame and 3.5e-16
# in the final beads; fmm 5.9e-16 (at 162 beads the two FMMs' products differ by round-off).
set(rigid_bd_common rigid-bd --positions "${WORK}/bodies.txt" --radius 0.5 --body-sizes "${WORK}/body_sizes.txt"
                    --viscosity 0.7 --dt 0.02 --kT 1 --seed 3 --body-force 0 0 -1 --body-torque 0.1 0 0
                    --solver-tolerance 1e-8 --sqrt-tolerance 1e-6)
run_serial(rigid_bd rigid_bd_serial ${rigid_bd_common} --steps 4 --every 2 --method direct --sqrt-preconditioner none
           --beads-out "${WORK}/rigid_bd_beads_serial.npy")
run_across(rigid_bd ${rigid_bd_common} --steps 4 --every 2 --method direct --beads-out "${WORK}/rigid_bd_beads_mpi.npy")
if(NOT json MATCHES "\"drift_iterations_per_step\":[1-9]" OR NOT json MATCHES "\"frames\":3,")
  message(FATAL_ERROR "rigid-bd: --json lacks the drift iterations or the 3 frames: ${json}")
endif()
agree(rigid_bd "${WORK}/rigid_bd_mpi.npy" "${WORK}/rigid_bd_serial.npy" 1e-11)
agree(rigid_bd "${WORK}/rigid_bd_beads_mpi.npy" "${WORK}/rigid_bd_beads_serial.npy" 1e-11)
run_across(rigid_bd_half ${rigid_bd_common} --steps 2 --method direct)
run_across(rigid_bd_rest ${rigid_bd_common} --steps 2 --method direct --restart "${WORK}/rigid_bd_half_mpi.npy"
           --first-step 2 --beads-out "${WORK}/rigid_bd_beads_rest.npy")
execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files "${WORK}/rigid_bd_beads_rest.npy"
                        "${WORK}/rigid_bd_beads_mpi.npy" RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "rigid-bd: the restart on ${NP} ranks does not end at the beads of the longer run")
endif()
run_serial(rigid_bd_fmm rigid_bd_fmm_serial ${rigid_bd_common} --steps 4 --method fmm --tolerance 1e-8
           --sqrt-preconditioner none)
run_across(rigid_bd_fmm ${rigid_bd_common} --steps 4 --method fmm --tolerance 1e-8)
agree(rigid_bd_fmm "${WORK}/rigid_bd_fmm_mpi.npy" "${WORK}/rigid_bd_fmm_serial.npy" 1e-5)
# --method pse in the periodic box of side 11 on the bodies given wrapped into it (the bodies
# centred at 10 straddle the faces, so their beads lie at both ends of the box: only minimum-image
# shapes, which both commands take, describe them; nothing else is wrapped) against the serial
# command with double wave grids, 3 steps: the bead products agree to 1e-12 (docs/mpi.md
# "Distributed PSE"), the split sampler's B z to round-off, each solve to 1e-9 (the bound of
# tests/mpi/test_distributed_rigid_periodic.cpp), and the RFD divides the difference of two solves
# by delta = 1e-3: within 1e-6 per frame and in the final beads (the bound of
# tests/mpi/test_distributed_rigid_bd.cpp). Measured at 2 and 3 ranks (shared 2-core AMD EPYC,
# AVX-512, 2026-12-07): at most 5.4e-16 (positions) and 1.7e-15 (orientations) per frame, 6.1e-16
# in the final beads; with the shapes taken in open space (no minimum images) 0.56.
string(REPLACE "bodies.txt" "bodies_wrapped.txt" rigid_bd_wrapped "${rigid_bd_common}")
run_serial(rigid_bd_pse rigid_bd_pse_serial ${rigid_bd_wrapped} --steps 3 --method pse --box 11 --wave-precision double
           --beads-out "${WORK}/rigid_bd_pse_beads_serial.npy")
run_across(rigid_bd_pse ${rigid_bd_wrapped} --steps 3 --method pse --box 11
           --beads-out "${WORK}/rigid_bd_pse_beads_mpi.npy")
if(NOT json MATCHES "\"method\":\"pse\"" OR NOT json MATCHES "\"drift_iterations_per_step\":[1-9]")
  message(FATAL_ERROR "rigid_bd_pse: --json lacks the method or the drift iterations: ${json}")
endif()
agree(rigid_bd_pse "${WORK}/rigid_bd_pse_mpi.npy" "${WORK}/rigid_bd_pse_serial.npy" 1e-6)
agree(rigid_bd_pse "${WORK}/rigid_bd_pse_beads_mpi.npy" "${WORK}/rigid_bd_pse_beads_serial.npy" 1e-6)

# rigid-bd --pair wca --pair-sigma 1.9 between the beads of different bodies (neighbouring bodies'
# beads lie about 2 apart, within the cut-off 2^(1/6) 1.9 = 2.13 and outside the hard core 0.8 x
# 1.9): every rank sums its own beads' forces over them and its halo in the serial order, bit for
# bit the serial bead forces at the same positions, so the trajectory differs from the serial
# command's only as without --pair: within 1e-11 with --method direct (4 steps); the field moves
# the bodies (the direct trajectory differs from rigid_bd's by more than 1e-6). In the box of side
# 11 with --method pse (3 steps), the bodies at both ends of the box lie 3 apart through its faces,
# their beads 1 apart: --pair soft --pair-sigma 2.5 (no hard core) acts through the faces (minimum
# images), within 1e-6 of the serial command with double wave grids, and moves the bodies by more
# than that. Measured at 2 and 3 ranks (shared 2-core AMD EPYC, AVX-512, 2026-12-07, b38316a;
# relative l2 per frame): direct at most 2.3e-16 (positions) and 6.2e-16 (orientations), 2.9e-16
# in the final beads; pse 6.2e-16 and 1.5e-15; the pair potentials move the bodies by 2.2e-3
# (direct) and 1.1e-4 (pse).
set(pair --pair wca --pair-sigma 1.9)
run_serial(rigid_bd_pair rigid_bd_pair_serial ${rigid_bd_common} ${pair} --steps 4 --every 2 --method direct
           --sqrt-preconditioner none --beads-out "${WORK}/rigid_bd_pair_beads_serial.npy")
run_across(rigid_bd_pair ${rigid_bd_common} ${pair} --steps 4 --every 2 --method direct
           --beads-out "${WORK}/rigid_bd_pair_beads_mpi.npy")
agree(rigid_bd_pair "${WORK}/rigid_bd_pair_mpi.npy" "${WORK}/rigid_bd_pair_serial.npy" 1e-11)
agree(rigid_bd_pair "${WORK}/rigid_bd_pair_beads_mpi.npy" "${WORK}/rigid_bd_pair_beads_serial.npy" 1e-11)
# Fails unless the trajectory with a pair potential (serial) lies beyond `bound` of the one without.
function(pair_moves name with without bound)
  execute_process(COMMAND "${AGREE}" "${with}" "${without}" ${bound} RESULT_VARIABLE rc OUTPUT_QUIET ERROR_QUIET)
  if(rc EQUAL 0)
    message(FATAL_ERROR "${name}: the pair potential leaves the trajectory within ${bound} of the one without it")
  endif()
endfunction()
pair_moves(rigid_bd_pair "${WORK}/rigid_bd_pair_serial.npy" "${WORK}/rigid_bd_serial.npy" 1e-6)
set(soft --pair soft --pair-sigma 2.5)
run_serial(rigid_bd_pair_pse rigid_bd_pair_pse_serial ${rigid_bd_wrapped} ${soft} --steps 3 --method pse --box 11
           --wave-precision double)
run_across(rigid_bd_pair_pse ${rigid_bd_wrapped} ${soft} --steps 3 --method pse --box 11)
agree(rigid_bd_pair_pse "${WORK}/rigid_bd_pair_pse_mpi.npy" "${WORK}/rigid_bd_pair_pse_serial.npy" 1e-6)
pair_moves(rigid_bd_pair_pse "${WORK}/rigid_bd_pair_pse_serial.npy" "${WORK}/rigid_bd_pse_serial.npy" 1e-6)

# Across ranks rigid-bd refuses the methods that do not run there, and fails every rank alike on
# bad input (also a --pair whose list radius exceeds half the box): exit status 2, one error line,
# no output.
if(NP GREATER 1)
  expect_one_error("rigid-bd --pair in a small box" "exceeds half the box length" "${WORK}/never.npy" "${RPYFMM}"
                   ${rigid_bd_wrapped} --steps 1 --method pse --box 11 --pair soft --pair-sigma 5
                   --out "${WORK}/never.npy")
  expect_one_error("rigid-bd --method pse --wave-precision single"
                   "rigid-bd: across ${NP} MPI ranks runs --method direct or fmm without --box, or --method pse with --box"
                   "${WORK}/never.npy" "${RPYFMM}" ${rigid_bd_common} --steps 1 --method pse --box 40
                   --wave-precision single --out "${WORK}/never.npy")
  expect_one_error("rigid-bd --rfd-delta" "rfd_delta" "${WORK}/never.npy" "${RPYFMM}" ${rigid_bd_common} --steps 1
                   --rfd-delta 0.5 --out "${WORK}/never.npy")
  expect_one_error("rigid-bd --restart" "--restart: expected a trajectory of shape" "${WORK}/never.npy" "${RPYFMM}"
                   ${rigid_bd_common} --steps 1 --restart "${WORK}/rigid_beads_mpi.npy" --out "${WORK}/never.npy")
  # rigid with a bead method that does not run across ranks refuses, naming what does.
  execute_process(COMMAND "${MPIEXEC}" -n ${NP} ${flags} "${RPYFMM}" ${rigid_common} --method pse --box 40
                          --wave-precision single --out "${WORK}/never.npy"
                  RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(rc EQUAL 0 OR NOT err MATCHES "rigid: across ${NP} MPI ranks runs --method direct or fmm without --box, or --method pse with --box" OR EXISTS
                                                                                          "${WORK}/never.npy")
    message(FATAL_ERROR "rigid --method pse --wave-precision single under ${NP} ranks: exit ${rc}: ${err}")
  endif()
  # mobility and sample with what does not run across ranks refuse too.
  foreach(case "mobility;--positions;${WORK}/x.txt;--radius;1;--forces;${WORK}/f.txt;--method;pse;--box;40;--wave-precision;single"
               "sample;--positions;${WORK}/x.txt;--radius;1;--operator;direct;--method;eigen")
    execute_process(COMMAND "${MPIEXEC}" -n ${NP} ${flags} "${RPYFMM}" ${case} --out "${WORK}/never.npy"
                    RESULT_VARIABLE rc ERROR_VARIABLE err)
    if(rc EQUAL 0 OR NOT err MATCHES "across ${NP} MPI ranks runs" OR EXISTS "${WORK}/never.npy")
      message(FATAL_ERROR "${case} under ${NP} ranks: exit ${rc}: ${err}")
    endif()
  endforeach()
endif()
file(REMOVE_RECURSE "${WORK}")

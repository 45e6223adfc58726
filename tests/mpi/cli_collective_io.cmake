# The command-line tool across ranks with collective I/O (docs/mpi.md, "The command-line tool under
# mpirun"): .npy inputs read by every rank with MPI-IO, the output written by every rank.
#  - mobility --method direct and sample --operator direct on .npy inputs (float64 and float32,
#    with --radii, --torques, --noise, sample --angular's (N,6) noise, a text file beside .npy
#    ones): the serial command's output byte for byte, with --io collective (the default) and with
#    --io root (rank 0 reads and writes whole);
#  - laplace (the ranks read their shares of the inputs, --direct then gathers every source and
#    charge, and write the (nd,M,10) result): --direct the serial output byte for byte with either
#    --io, --tolerance the same bytes with either --io;
#  - bad inputs and outputs (NaN in a row that only rank 1 reads, NaN in a radius of the last
#    rank's, NaN in a charge of the second density, a short file, an unsupported dtype, forces with a row too few, --out naming an input,
#    a symbolic link or a directory): exit status 2, one error line holding the serial command's
#    message, no output and no temporary file left.
# With -DPART=bodies it runs the cases of rigid, rigid-bd and laplace --direct instead
# (cli_collective_io_bodies.cmake).
# Run by ctest as
#   cmake -DRPYFMM=... -DMPIEXEC=... -DNP=... "-DMPI_FLAGS=..." -DFIXTURE=... -DAGREE=... -DWORK=... \
#         [-DPART=bodies] -P cli_collective_io.cmake
cmake_minimum_required(VERSION 3.20)
foreach(var RPYFMM MPIEXEC NP FIXTURE AGREE WORK)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "cli_collective_io.cmake: -D${var}=... is required")
  endif()
endforeach()
separate_arguments(flags UNIX_COMMAND "${MPI_FLAGS}")
file(REMOVE_RECURSE "${WORK}")
file(MAKE_DIRECTORY "${WORK}")

# 301 particles (not a multiple of 2 or 3: the shares differ in size) on a lattice of spacing 3
# with a jitter below 0.1, forces and torques in [-1, 1], radii in [0.5, 1.5).
set(x "")
set(q2 "")
set(q2_negative "")
set(f "")
set(a "")
set(z6 "")
foreach(i RANGE 300)
  math(EXPR ix "(${i} % 7) * 3000 + (${i} * 37) % 100")
  math(EXPR iy "(${i} / 7 % 7) * 3000 + (${i} * 53) % 100")
  math(EXPR iz "(${i} / 49) * 3000 + (${i} * 71) % 100")
  math(EXPR fx "(${i} * 17) % 201 - 100")
  math(EXPR fy "(${i} * 29) % 201 - 100")
  math(EXPR fz "(${i} * 41) % 201 - 100")
  math(EXPR ai "500 + (${i} * 89) % 1000")
  string(APPEND x "${ix}e-3 ${iy}e-3 ${iz}e-3\n")
  string(APPEND f "${fx}e-2 ${fy}e-2 ${fz}e-2\n")
  string(APPEND a "${ai}e-3\n")
  string(APPEND z6 "${fx}e-2 ${fy}e-2 ${fz}e-2 ${fz}e-2 ${fx}e-2 ${fy}e-2\n")
  string(APPEND q2 " ${ai}e-3")
  string(APPEND q2_negative " -${ai}e-3")
endforeach()
# Two densities for laplace: the radii's values and their negatives.
file(WRITE "${WORK}/q2.txt" "${q2}\n${q2_negative}\n")
string(REGEX REPLACE "[^\n]*\n$" "" f_short "${f}")
file(WRITE "${WORK}/x.txt" "${x}")
file(WRITE "${WORK}/f.txt" "${f}")
file(WRITE "${WORK}/f_short.txt" "${f_short}")
file(WRITE "${WORK}/a.txt" "${a}")
file(WRITE "${WORK}/z6.txt" "${z6}")

# ${WORK}/<out>.npy: the text file <in>.txt as .npy of `kind` (npy_fixture).
function(fixture in out kind)
  execute_process(COMMAND "${FIXTURE}" "${WORK}/${in}.txt" "${WORK}/${out}.npy" ${kind} RESULT_VARIABLE rc
                  ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "npy_fixture ${in} ${out} ${kind} failed: ${err}")
  endif()
endfunction()
fixture(x x f8)
fixture(x x4 f4)
fixture(f f f8)
fixture(f_short f_short f8)
fixture(a a f8)
fixture(z6 z6 f8)
fixture(q2 q2 f8)
# Row 200 lies in rank 1's share on 2 and 3 ranks (rank 0 holds rows 0-150, or 0-100), radius 250
# in the last rank's.
fixture(x x_nan nan:601)
fixture(a a_nan nan:250)
fixture(x x_short short)
fixture(x x_i4 i4)
# Charge 249 of the second density: the last rank's share on 2 and 3 ranks.
fixture(q2 q2_nan nan:550)

# No temporary file (<name>.tmp.<hex>) left in ${WORK} or in `dir`.
function(require_no_temporary name dir)
  file(GLOB left "${WORK}/*.tmp.*" "${dir}/*.tmp.*")
  if(left)
    message(FATAL_ERROR "${name} under ${NP} ranks left temporary files: ${left}")
  endif()
endfunction()

# `args` across NP ranks with --io `io`, writing ${WORK}/<name>_<io>.npy.
function(run_across name io)
  execute_process(COMMAND "${MPIEXEC}" -n ${NP} ${flags} "${RPYFMM}" ${ARGN} --io ${io} --out "${WORK}/${name}_${io}.npy"
                  RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${name}: mpiexec -n ${NP} rpyfmm ${ARGN} --io ${io} failed (${rc}): ${err}")
  endif()
  require_no_temporary(${name} "${WORK}")
endfunction()
# Files `a` and `b` in ${WORK} hold the same bytes.
function(require_same name a b)
  execute_process(COMMAND "${CMAKE_COMMAND}" -E compare_files "${WORK}/${a}.npy" "${WORK}/${b}.npy"
                  RESULT_VARIABLE differ)
  if(NOT differ EQUAL 0)
    message(FATAL_ERROR "${name} under ${NP} ranks: ${a}.npy differs from ${b}.npy")
  endif()
endfunction()
# The serial command `args` and the same across NP ranks with --io `io` write the same bytes.
function(run_identical name io)
  execute_process(COMMAND "${RPYFMM}" ${ARGN} --out "${WORK}/${name}_serial.npy" RESULT_VARIABLE rc
                  ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${name}: serial rpyfmm ${ARGN} failed (${rc}): ${err}")
  endif()
  run_across(${name} ${io} ${ARGN})
  require_same(${name} ${name}_serial ${name}_${io})
endfunction()

# `args` fails serially with exit status 2 and one message; across NP ranks (collective I/O) it must
# fail alike: exit status 2, one error line holding the serial message, nothing at `out`, no
# temporary file in `out`'s folder or in ${WORK}.
function(expect_serial_error name out)
  execute_process(COMMAND "${RPYFMM}" ${ARGN} --out "${out}" RESULT_VARIABLE rc ERROR_VARIABLE serial)
  string(REGEX REPLACE "^rpyfmm: error: ([^\n]*)\n?$" "\\1" message "${serial}")
  if(NOT rc EQUAL 2 OR message STREQUAL serial)
    message(FATAL_ERROR "${name}: the serial command did not fail with one message (${rc}): ${serial}")
  endif()
  execute_process(COMMAND "${MPIEXEC}" -n ${NP} ${flags} "${RPYFMM}" ${ARGN} --out "${out}" RESULT_VARIABLE rc
                  ERROR_VARIABLE err)
  string(REGEX MATCHALL "rpyfmm: error:" errors "${err}")
  list(LENGTH errors count)
  string(FIND "${err}" "${message}" at)
  if(NOT rc EQUAL 2 OR NOT count EQUAL 1 OR at EQUAL -1)
    message(FATAL_ERROR "${name} under ${NP} ranks: exit ${rc}, ${count} error lines, not '${message}': ${err}")
  endif()
  get_filename_component(dir "${out}" DIRECTORY)
  require_no_temporary(${name} "${dir}")
endfunction()
function(expect_no_output name)
  set(never "${WORK}/never.npy")
  expect_serial_error(${name} "${never}" ${ARGN})
  if(EXISTS "${never}")
    message(FATAL_ERROR "${name} under ${NP} ranks wrote ${never}")
  endif()
endfunction()

# -DPART=bodies: the cases of rigid, rigid-bd and laplace --direct instead
# (tests/mpi/cli_collective_io_bodies.cmake), a test of its own.
if(PART STREQUAL "bodies")
  include("${CMAKE_CURRENT_LIST_DIR}/cli_collective_io_bodies.cmake")
  return()
endif()

set(mobility mobility --positions "${WORK}/x.npy" --forces "${WORK}/f.npy" --viscosity 0.7 --method direct)
set(sample sample --positions "${WORK}/x.npy" --radii "${WORK}/a.npy" --viscosity 0.7 --operator direct
           --method lanczos --sqrt-tolerance 1e-6 --preconditioner none)
foreach(io collective root)
  run_identical(mobility_radii ${io} ${mobility} --radii "${WORK}/a.npy")
  run_identical(sample_angular ${io} ${sample} --angular --noise "${WORK}/z6.npy")
endforeach()
run_identical(mobility_torques collective ${mobility} --radius 1.1 --torques "${WORK}/f.npy")
run_identical(sample_noise collective ${sample} --noise "${WORK}/f.npy")
# laplace writes its (nd,M,10) result with every rank's rows of each density: --direct (every rank
# reading its shares, then gathering the sources and charges) the serial file byte for byte; the FMM across ranks (each rank reading its shares of the
# sources, the targets and each density's charges) is not the serial FMM's bits, but the same
# computation writes the same bytes with either --io.
set(laplace laplace --sources "${WORK}/x.npy" --charges "${WORK}/q2.npy" --targets "${WORK}/f.npy")
run_identical(laplace_direct collective ${laplace} --direct)
run_identical(laplace_direct root ${laplace} --direct)
run_across(laplace_fmm collective ${laplace} --tolerance 1e-6)
run_across(laplace_fmm root ${laplace} --tolerance 1e-6)
require_same(laplace_fmm laplace_fmm_collective laplace_fmm_root)
# float32 positions (widened as the serial reader does) and text forces beside .npy positions.
run_identical(mobility_f4 collective mobility --positions "${WORK}/x4.npy" --forces "${WORK}/f.npy" --radius 1.1
              --method direct)
run_identical(mobility_text collective mobility --positions "${WORK}/x.npy" --forces "${WORK}/f.txt" --radius 1.1
              --method direct)

expect_no_output(positions_nan mobility --positions "${WORK}/x_nan.npy" --forces "${WORK}/f.npy" --radius 1)
expect_no_output(radii_nan mobility --positions "${WORK}/x.npy" --forces "${WORK}/f.npy" --radii "${WORK}/a_nan.npy")
expect_no_output(positions_short mobility --positions "${WORK}/x_short.npy" --forces "${WORK}/f.npy" --radius 1)
expect_no_output(positions_i4 mobility --positions "${WORK}/x_i4.npy" --forces "${WORK}/f.npy" --radius 1)
expect_no_output(forces_short mobility --positions "${WORK}/x.npy" --forces "${WORK}/f_short.npy" --radius 1)
expect_no_output(charges_nan laplace --sources "${WORK}/x.npy" --charges "${WORK}/q2_nan.npy" --tolerance 1e-6)
expect_no_output(noise_short sample --positions "${WORK}/x.npy" --radius 1 --noise "${WORK}/f_short.npy")
# --out naming an input, a symbolic link (to a good file, left as it was) and a directory.
set(good "${WORK}/mobility_radii_serial.npy")
file(SHA256 "${good}" good_hash)
file(CREATE_LINK "${good}" "${WORK}/link.npy" SYMBOLIC)
file(MAKE_DIRECTORY "${WORK}/folder.npy")
foreach(out "${WORK}/x.npy" "${WORK}/link.npy" "${WORK}/folder.npy")
  expect_serial_error("--out ${out}" "${out}" mobility --positions "${WORK}/x.npy" --forces "${WORK}/f.npy" --radius 1)
endforeach()
file(SHA256 "${good}" hash)
file(READ_SYMLINK "${WORK}/link.npy" target)
if(NOT hash STREQUAL good_hash OR NOT target STREQUAL good OR NOT IS_DIRECTORY "${WORK}/folder.npy")
  message(FATAL_ERROR "a refused --out under ${NP} ranks changed the file, the link or the folder")
endif()


# The command-line tool across ranks with collective I/O, the commands on rigid bodies and laplace
# --direct (docs/mpi.md, "The command-line tool under mpirun"), included by cli_collective_io.cmake
# with -DPART=bodies after its fixtures and helpers:
#  - rigid and rigid-bd --method direct on .npy beads, radii, reference points and forces (text body
#    sizes): the same bytes with --io collective and --io root (outputs and the bead forces or the
#    final beads), the serial command's files to round-off; a restart of rigid-bd from a trajectory
#    written collectively, the same bytes with either --io;
#  - laplace --direct at the sources with (N,) charges: the serial file byte for byte;
#  - bad inputs (NaN in a bead that only a later rank reads, NaN in the last rank's radius, body
#    sizes that are not whole numbers, forces of another count, reference points of another count,
#    a restart of another shape, NaN in a charge of the second density with --direct): exit status
#    2 on every rank, one line holding the serial command's message, no output, no temporary file,
#    and a file already at --out left as it was;
#  - hostile outputs (an input, a symbolic link to a good file, a device, a missing folder): refused
#    alike, the link and its file left as they were; a second output (rigid --bead-forces, rigid-bd
#    --beads-out) in a missing folder: refused with no first output, with either --io.
# rigid and rigid-bd across ranks read their bodies' rows of the .npy inputs (each rank whole
# bodies; --body-sizes, text, read by rank 0) and write their rows of the outputs. 301 beads in 60
# bodies of 3, 4, 5, 6, 7, ... beads (the last of 8): body k about the point k of a lattice of
# spacing 6 (4 x 4 x 4), its beads at the first corners of an octahedron of half-diagonal 1 and then
# (1,1,1) and (-1,-1,-1), each coordinate shifted by a jitter below 0.1; reference points 0.3 off
# each body's centre; forces and torques in [-1, 1].
set(corners "1,0,0;0,1,0;0,0,1;-1,0,0;0,-1,0;0,0,-1;1,1,1;-1,-1,-1")
set(beads "")
set(sizes "")
set(reference "")
set(body_forces "")
set(first 0)
foreach(k RANGE 59)
  math(EXPR size "3 + ${k} % 5")
  if(k EQUAL 59)
    math(EXPR size "301 - ${first}")
  endif()
  string(APPEND sizes "${size}\n")
  math(EXPR cx "(${k} % 4) * 6000")
  math(EXPR cy "(${k} / 4 % 4) * 6000")
  math(EXPR cz "(${k} / 16) * 6000")
  math(EXPR rx "${cx} + 300")
  string(APPEND reference "${rx}e-3 ${cy}e-3 ${cz}e-3\n")
  math(EXPR last "${size} - 1")
  foreach(j RANGE ${last})
    list(GET corners ${j} corner)
    string(REPLACE "," ";" corner "${corner}")
    list(GET corner 0 dx)
    list(GET corner 1 dy)
    list(GET corner 2 dz)
    math(EXPR i "${first} + ${j}")
    math(EXPR bx "${cx} + 1000 * ${dx} + (${i} * 37) % 100")
    math(EXPR by "${cy} + 1000 * ${dy} + (${i} * 53) % 100")
    math(EXPR bz "${cz} + 1000 * ${dz} + (${i} * 71) % 100")
    string(APPEND beads "${bx}e-3 ${by}e-3 ${bz}e-3\n")
  endforeach()
  set(row "")
  foreach(c RANGE 5)
    math(EXPR v "(${k} * (17 + 12 * ${c})) % 201 - 100")
    string(APPEND row " ${v}e-2")
  endforeach()
  string(APPEND body_forces "${row}\n")
  math(EXPR first "${first} + ${size}")
endforeach()
file(WRITE "${WORK}/bx.txt" "${beads}")
file(WRITE "${WORK}/sizes.txt" "${sizes}")
file(WRITE "${WORK}/ref.txt" "${reference}")
file(WRITE "${WORK}/ft.txt" "${body_forces}")
fixture(bx bx f8)
fixture(bx bx_nan nan:601)
fixture(ref ref f8)
fixture(ft ft f8)

# The files of `args` across NP ranks with --io collective and --io root: the same bytes, `out` and
# the extra output `extra_option` (written to ${WORK}/<name>_<extra>_<io>.npy).
function(run_both_io name extra_option extra)
  foreach(io collective root)
    run_across(${name} ${io} ${ARGN} ${extra_option} "${WORK}/${name}_${extra}_${io}.npy")
  endforeach()
  require_same(${name} ${name}_collective ${name}_root)
  require_same(${name} ${name}_${extra}_collective ${name}_${extra}_root)
endfunction()
# `a` and `b` in ${WORK} agree to `bound` (relative l2 per output, tests/mpi/laplace_agree.cpp).
function(require_agree name a b bound)
  execute_process(COMMAND "${AGREE}" "${WORK}/${a}.npy" "${WORK}/${b}.npy" ${bound} RESULT_VARIABLE rc
                  OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${name} under ${NP} ranks: ${a}.npy against ${b}.npy beyond ${bound}: ${out}${err}")
  endif()
endfunction()
# The serial command `args` (with `serial_only`, a list, too) and the same across NP ranks with
# either --io (run_both_io, the extra output of `extra_option` named beads): within `bound` of the
# serial files, both outputs.
function(run_against_serial name extra_option bound serial_only)
  execute_process(COMMAND "${RPYFMM}" ${ARGN} ${serial_only} --out "${WORK}/${name}_serial.npy" ${extra_option}
                          "${WORK}/${name}_beads_serial.npy" RESULT_VARIABLE rc ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${name}: the serial command failed (${rc}): ${err}")
  endif()
  run_both_io(${name} ${extra_option} beads ${ARGN})
  require_agree(${name} ${name}_collective ${name}_serial ${bound})
  require_agree(${name} ${name}_beads_collective ${name}_beads_serial ${bound})
endfunction()
# rigid --method direct: the ranks' GMRES sums its inner products in another order than the serial
# solver's, so the files are the serial command's to round-off, within 1e-12 relative (the bound of
# tests/mpi/test_distributed_rigid.cpp), and the two --io settings' the same bytes (the same
# computation on the same values).
set(rigid rigid --positions "${WORK}/bx.npy" --radii "${WORK}/a.npy" --body-sizes "${WORK}/sizes.txt" --reference
          "${WORK}/ref.npy" --forces "${WORK}/ft.npy" --viscosity 0.7 --method direct --solver-tolerance 1e-10)
run_against_serial(rigid --bead-forces 1e-12 "" ${rigid})
# rigid-bd --method direct, 2 steps at kT 1 with the RFD drift, a frame every step: the serial
# trajectory with --sqrt-preconditioner none (the ranks' default) to round-off, within 1e-11 per
# frame and in the final beads (the bound of tests/mpi/test_distributed_rigid_bd.cpp: GMRES's
# inner products summed in another order, through the RFD's 1 / delta); a restart from its last
# frame with either --io the same bytes.
set(rigid_bd rigid-bd --positions "${WORK}/bx.npy" --radius 0.5 --body-sizes "${WORK}/sizes.txt" --viscosity 0.7
             --dt 0.02 --kT 1 --seed 3 --body-force 0 0 -1 --solver-tolerance 1e-8 --sqrt-tolerance 1e-6
             --method direct --steps 2 --every 1)
run_against_serial(rigid_bd --beads-out 1e-11 "--sqrt-preconditioner;none" ${rigid_bd})
run_both_io(rigid_bd_restart --beads-out beads ${rigid_bd} --restart "${WORK}/rigid_bd_collective.npy" --first-step 2)
# laplace --direct at the sources with one density ((N,) charges): the serial file byte for byte.
run_identical(laplace_direct_sources collective laplace --sources "${WORK}/x.npy" --charges "${WORK}/a.npy" --direct)

# Bad inputs of the three commands: the serial message, exit status 2 on every rank, no output.
set(sizes_args --body-sizes "${WORK}/sizes.txt")
set(ft_args --forces "${WORK}/ft.npy" --method direct)
set(x_args --positions "${WORK}/bx.npy" --radius 0.5)
expect_no_output(rigid_radii_nan rigid --positions "${WORK}/bx.npy" --radii "${WORK}/a_nan.npy" ${sizes_args}
                 ${ft_args})
expect_no_output(rigid_sizes_whole rigid ${x_args} --body-sizes "${WORK}/a.txt" ${ft_args})
expect_no_output(rigid_forces_count rigid ${x_args} ${sizes_args} --forces "${WORK}/f.npy" --method direct)
expect_no_output(rigid_reference_rows rigid ${x_args} ${sizes_args} ${ft_args} --reference "${WORK}/x.npy")
expect_no_output(laplace_direct_charges_nan laplace --sources "${WORK}/x.npy" --charges "${WORK}/q2_nan.npy" --direct)
# NaN in bead 200 (rank 1's share of the bodies on 2 ranks, rank 1's or 2's on 3) and a restart of
# another shape: a failed run leaves a file already at --out as it was.
file(COPY_FILE "${WORK}/rigid_collective.npy" "${WORK}/kept.npy")
file(SHA256 "${WORK}/kept.npy" kept_hash)
expect_serial_error(rigid_positions_nan "${WORK}/kept.npy" rigid --positions "${WORK}/bx_nan.npy" --radius 0.5
                    ${sizes_args} ${ft_args})
expect_serial_error(rigid_bd_restart_shape "${WORK}/kept.npy" ${rigid_bd} --restart "${WORK}/rigid_collective.npy")
file(SHA256 "${WORK}/kept.npy" hash)
if(NOT hash STREQUAL kept_hash)
  message(FATAL_ERROR "a failed rigid or rigid-bd under ${NP} ranks changed the file at --out")
endif()
# Hostile outputs: an input, a symbolic link to a good file, a device and a missing folder (for
# rigid-bd's second output too), refused with the serial message; the link and its file unchanged.
set(good "${WORK}/rigid_serial.npy")
file(SHA256 "${good}" good_hash)
file(CREATE_LINK "${good}" "${WORK}/link.npy" SYMBOLIC)
set(rigid_small rigid ${x_args} ${sizes_args} ${ft_args})
foreach(out "${WORK}/ft.npy" "${WORK}/link.npy" /dev/null "${WORK}/missing/out.npy")
  expect_serial_error("rigid --out ${out}" "${out}" ${rigid_small})
endforeach()
# A second output in a missing folder: refused before either file is in place, so no first output
# either (the outputs are renamed together once both are written), with either --io.
foreach(io collective root)
  expect_no_output("rigid-bd --beads-out missing, --io ${io}" ${rigid_bd} --io ${io} --beads-out
                   "${WORK}/missing/b.npy")
  expect_no_output("rigid --bead-forces missing, --io ${io}" ${rigid_small} --io ${io} --bead-forces
                   "${WORK}/missing/b.npy")
endforeach()
expect_serial_error("laplace --direct --out link" "${WORK}/link.npy" laplace --sources "${WORK}/x.npy" --charges
                    "${WORK}/a.npy" --direct)
file(SHA256 "${good}" hash)
file(READ_SYMLINK "${WORK}/link.npy" target)
if(NOT hash STREQUAL good_hash OR NOT target STREQUAL good OR EXISTS "${WORK}/missing")
  message(FATAL_ERROR "a refused rigid, rigid-bd or laplace --out under ${NP} ranks changed the link or its file")
endif()

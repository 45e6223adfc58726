# `mpiexec -n NP rpyfmm bd` against the serial command on the same configuration (docs/mpi.md,
# "Brownian dynamics across ranks"). With free draining the positions after every step are the
# serial engine's bit for bit, so the trajectory files must be identical byte for byte:
#  - a run of 60 steps on NP ranks (frames every 10, a checkpoint every 30);
#  - the first 30 steps on 2 ranks, then a restart from their checkpoint on NP ranks;
#  - 60 steps on NP ranks on Hilbert-curve partitions, repartitioned at every rebuild ([partition]).
# With PSE (spheres of one radius, double-precision wave grids) the positions are the serial
# engine's to round-off (about 1e-15 of the coordinates; tests/mpi/test_distributed_bd.cpp), so
# the printed coordinates (10 significant digits) agree to one unit of their last digit, allowed 2.
# Bead-spring chains, rotating dipoles and Langevin types (free draining; dipoles and Langevin
# types also restarted, the latter from a checkpoint with velocities): byte for byte as free
# draining; rotating dipoles with PSE: to round-off as PSE. With split displacements (free
# draining) the trajectory byte for byte and the log's split columns character for character. The
# SAC scheme (free draining, also restarted): the trajectory with its complex column byte for byte,
# the log's complexes and mean_adsorbed columns character for character. A configuration the
# ranks do not run (direct in a periodic box; PSE with single-precision grids) fails every rank:
# exit status 2, one error line, no output directory. Run by ctest as
#   cmake -DRPYFMM=... -DMPIEXEC=... -DNP=... "-DMPI_FLAGS=..." -DWORK=... -P bd_across_ranks.cmake
cmake_minimum_required(VERSION 3.20)
foreach(var RPYFMM MPIEXEC NP WORK)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "bd_across_ranks.cmake: -D${var}=... is required")
  endif()
endforeach()
separate_arguments(flags UNIX_COMMAND "${MPI_FLAGS}")
file(REMOVE_RECURSE "${WORK}")
file(MAKE_DIRECTORY "${WORK}")

# 600 spheres of two sizes with WCA pairs in a periodic box (volume fraction 0.12).
file(WRITE "${WORK}/run.toml" [=[
[system]
geometry = "periodic"
box = [14.0, 14.0, 14.0]
[[types]]
name = "A"
radius = 0.5
[[types]]
name = "B"
radius = 0.7
[particles]
source = "random"
count = 600
[[pair]]
types = ["A", "A"]
kind = "wca"
[[pair]]
types = ["A", "B"]
kind = "wca"
[[pair]]
types = ["B", "B"]
kind = "wca"
[integrator]
dt = 0.004
steps = 60
seed = 11
[mobility]
method = "none"
[output]
trajectory_every = 10
log_every = 10
checkpoint_every = 30
]=])

function(run_bd ranks)
  if(ranks EQUAL 0)
    set(launcher "")
  else()
    set(launcher "${MPIEXEC}" -n ${ranks} ${flags})
  endif()
  execute_process(COMMAND ${launcher} "${RPYFMM}" bd ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out
                  ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "rpyfmm bd ${ARGN} on ${ranks} ranks: exit ${rc}: ${err}")
  endif()
  set(run_output "${out}" PARENT_SCOPE)
endfunction()

function(same_trajectory a b what)
  execute_process(COMMAND "${CMAKE_COMMAND}" -E compare_files "${WORK}/${a}/trajectory.xyz" "${WORK}/${b}/trajectory.xyz"
                  RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what}: the trajectory differs from the serial run's")
  endif()
endfunction()

# The run of ${WORK}/NAME.toml (60 steps) on NP ranks, and its first 30 steps on 2 ranks restarted
# from their checkpoint on NP, against the serial run: trajectories identical byte for byte.
function(same_as_serial name what)
  run_bd(0 --config "${WORK}/${name}.toml" --out-dir "${WORK}/${name}_serial" --quiet)
  run_bd(${NP} --config "${WORK}/${name}.toml" --out-dir "${WORK}/${name}_ranks" --json)
  if(NOT run_output MATCHES "\"ranks\":${NP}" OR NOT run_output MATCHES "\"last_step\":60"
     OR NOT run_output MATCHES "\"engine\":\"mpi\"")
    message(FATAL_ERROR "${what}: --json across ${NP} ranks: ${run_output}")
  endif()
  same_trajectory(${name}_serial ${name}_ranks "${what}, 60 steps on ${NP} ranks")
  run_bd(2 --config "${WORK}/${name}.toml" --out-dir "${WORK}/${name}_restarted" --steps 30 --quiet)
  run_bd(${NP} --restart "${WORK}/${name}_restarted/checkpoint.bin" --quiet)
  same_trajectory(${name}_serial ${name}_restarted "${what}, 30 steps on 2 ranks, 30 more on ${NP}")
endfunction()

same_as_serial(run "free draining")

# [partition]: Hilbert-curve partitions, repartitioned at every rebuild. Free-draining positions do
# not depend on the partition, so the trajectory is the serial run's byte for byte.
file(READ "${WORK}/run.toml" text)
file(WRITE "${WORK}/hilbert.toml"
     "${text}\n[partition]\ncurve = \"hilbert\"\nrepartition_imbalance = 1.0\nrepartition_cost = \"model\"\n")
run_bd(${NP} --config "${WORK}/hilbert.toml" --out-dir "${WORK}/hilbert_ranks" --quiet)
same_trajectory(run_serial hilbert_ranks "free draining on Hilbert-curve partitions, 60 steps on ${NP} ranks")

# Whether two coordinates printed with 10 significant digits differ by at most 2 units of their
# last digit (the same number of decimals; as integers without the point).
function(close_in_last_digit a b result)
  set(${result} FALSE PARENT_SCOPE)
  foreach(v a b)
    if(NOT ${v} MATCHES "^(-?)([0-9]+)\\.([0-9]+)$")
      return()
    endif()
    set(sign "${CMAKE_MATCH_1}")
    set(${v}_decimals "${CMAKE_MATCH_3}")
    string(REGEX REPLACE "^0+([0-9])" "\\1" digits "${CMAKE_MATCH_2}${CMAKE_MATCH_3}")
    set(${v}_int "${sign}${digits}")
  endforeach()
  string(LENGTH "${a_decimals}" la)
  string(LENGTH "${b_decimals}" lb)
  if(NOT la EQUAL lb)
    return()
  endif()
  math(EXPR d "${a_int} - (${b_int})")
  if(d LESS_EQUAL 2 AND d GREATER_EQUAL -2)
    set(${result} TRUE PARENT_SCOPE)
  endif()
endfunction()

function(close_trajectory a b what)
  file(STRINGS "${WORK}/${a}/trajectory.xyz" lines_a)
  file(STRINGS "${WORK}/${b}/trajectory.xyz" lines_b)
  list(LENGTH lines_a na)
  list(LENGTH lines_b nb)
  if(NOT na EQUAL nb OR na EQUAL 0)
    message(FATAL_ERROR "${what}: ${na} lines against the serial run's ${nb}")
  endif()
  set(differing 0)
  math(EXPR last "${na} - 1")
  foreach(k RANGE ${last})
    list(GET lines_a ${k} la)
    list(GET lines_b ${k} lb)
    if(la STREQUAL lb)
      continue()
    endif()
    string(REPLACE " " ";" ta "${la}")
    string(REPLACE " " ";" tb "${lb}")
    list(LENGTH ta nta)
    list(LENGTH tb ntb)
    if(NOT nta EQUAL ntb)
      message(FATAL_ERROR "${what}: line ${k} differs from the serial run's: ${la} | ${lb}")
    endif()
    math(EXPR tlast "${nta} - 1")
    foreach(t RANGE ${tlast})
      list(GET ta ${t} x)
      list(GET tb ${t} y)
      if(NOT x STREQUAL y)
        close_in_last_digit("${x}" "${y}" close)
        if(NOT close)
          message(FATAL_ERROR "${what}: line ${k} differs from the serial run's: ${la} | ${lb}")
        endif()
        math(EXPR differing "${differing} + 1")
      endif()
    endforeach()
  endforeach()
  message(STATUS "${what}: ${differing} printed coordinates differ in their last digit")
endfunction()

# PSE: spheres of one radius, 1e-4, double-precision wave grids; 40 steps.
file(READ "${WORK}/run.toml" text)
string(REPLACE "radius = 0.7" "radius = 0.5" pse "${text}")
string(REPLACE "method = \"none\"" "method = \"pse\"\ntolerance = 1e-4\nwave_precision = \"double\"" pse "${pse}")
string(REPLACE "steps = 60" "steps = 40" pse "${pse}")
file(WRITE "${WORK}/pse.toml" "${pse}")
run_bd(0 --config "${WORK}/pse.toml" --out-dir "${WORK}/pse_serial" --quiet)
run_bd(${NP} --config "${WORK}/pse.toml" --out-dir "${WORK}/pse_ranks" --quiet)
close_trajectory(pse_ranks pse_serial "PSE, 40 steps on ${NP} ranks")

# Rotation: dipoles of type A in a field, free draining: orientations, like positions, are the
# serial engine's bit for bit, so the trajectory (with its orientation column) is identical byte for
# byte; also after 30 steps on 2 ranks and a restart from their checkpoint (version 3) on NP.
string(REPLACE "geometry = \"periodic\"" "geometry = \"periodic\"\nrotation = true" rotation "${text}")
string(REPLACE "name = \"A\"\nradius = 0.5" "name = \"A\"\nradius = 0.5\ndipole = 2.0" rotation "${rotation}")
file(WRITE "${WORK}/rotation.toml" "${rotation}\n[external]\ndipole_field = [0.0, 0.0, 1.5]\n")
same_as_serial(rotation "rotation")
# Rotation with PSE (the dipoles of type A in the field, 20 steps): the grand product and PseRpy's
# split sampler with rotation, its wave noise keyed by the whole noise in global index order, so
# the trajectory with its orientations is the serial run's to round-off, as with PSE above.
string(REPLACE "geometry = \"periodic\"" "geometry = \"periodic\"\nrotation = true" pse_rotation "${pse}")
string(REPLACE "name = \"A\"\nradius = 0.5" "name = \"A\"\nradius = 0.5\ndipole = 2.0" pse_rotation
               "${pse_rotation}")
string(REPLACE "steps = 40" "steps = 20" pse_rotation "${pse_rotation}")
file(WRITE "${WORK}/pse_rotation.toml" "${pse_rotation}\n[external]\ndipole_field = [0.0, 0.0, 1.5]\n")
run_bd(0 --config "${WORK}/pse_rotation.toml" --out-dir "${WORK}/pse_rotation_serial" --quiet)
run_bd(${NP} --config "${WORK}/pse_rotation.toml" --out-dir "${WORK}/pse_rotation_ranks" --quiet)
close_trajectory(pse_rotation_ranks pse_rotation_serial "PSE with rotation, 20 steps on ${NP} ranks")

# Langevin types: the spheres alternate between A and B, the larger (B) inertial (gamma dt / m =
# 0.92), free draining: positions and half-step velocities are the serial engine's bit for bit, so
# the trajectory is identical byte for byte; also after 30 steps on 2 ranks and a restart from
# their checkpoint (version 4, with the velocities) on NP. The log across ranks has the kinetic
# temperature column (some particles are inertial).
string(REPLACE "name = \"B\"\nradius = 0.7" "name = \"B\"\nradius = 0.7\ndynamics = \"langevin\"\ndensity = 0.04"
               langevin "${text}")
string(REPLACE "count = 600" "count = 600\ntypes = [\"A\", \"B\"]" langevin "${langevin}")
file(WRITE "${WORK}/langevin.toml" "${langevin}")
same_as_serial(langevin "Langevin types")
file(STRINGS "${WORK}/langevin_ranks/log.csv" langevin_header LIMIT_COUNT 1)
if(NOT langevin_header MATCHES ",langevin_kT")
  message(FATAL_ERROR "Langevin types: the log across ${NP} ranks has no langevin_kT column: ${langevin_header}")
endif()

# The last two columns of the logs of ${WORK}/SERIAL and ${WORK}/RANKS agree character for
# character from row FIRST on (row 0 is the header, which must end with HEADER), and the serial
# run's are never "0,..." (the columns hold something).
function(same_log_tail serial ranks header first what)
  file(STRINGS "${WORK}/${serial}/log.csv" serial_rows)
  file(STRINGS "${WORK}/${ranks}/log.csv" ranks_rows)
  list(GET ranks_rows 0 ranks_header)
  if(NOT ranks_header MATCHES "${header}$")
    message(FATAL_ERROR "${what}: the log across ${NP} ranks has no columns ${header}: ${ranks_header}")
  endif()
  list(LENGTH serial_rows rows)
  list(LENGTH ranks_rows rows_ranks)
  if(NOT rows EQUAL rows_ranks OR rows LESS 3)
    message(FATAL_ERROR "${what}: ${rows_ranks} log lines against the serial run's ${rows}")
  endif()
  math(EXPR last "${rows} - 1")
  foreach(k RANGE ${first} ${last})
    foreach(r serial_rows ranks_rows)
      list(GET ${r} ${k} row)
      string(REGEX MATCH "[^,]*,[^,]*$" ${r}_tail "${row}")
    endforeach()
    if(NOT serial_rows_tail STREQUAL ranks_rows_tail OR serial_rows_tail MATCHES "^0,")
      message(FATAL_ERROR "${what}: log row ${k} ends '${ranks_rows_tail}' on ${NP} ranks, "
                          "'${serial_rows_tail}' serially")
    endif()
  endforeach()
endfunction()

# The SAC scheme on the Langevin types' configuration (B carriers, A adsorbers within
# R_A = 1.5 (a_A + a_B) = 1.8): positions, velocities and complexes are the serial engine's bit for
# bit, so the trajectory (with each particle's complex) is identical byte for byte, also after a
# restart, and the log's complexes and mean_adsorbed columns (its last two; the others hold
# timings) are the serial run's character for character.
string(REPLACE "seed = 11" "seed = 11\nscheme = \"sac\"\nadsorption_factor = 1.5" sac "${langevin}")
file(WRITE "${WORK}/sac.toml" "${sac}")
same_as_serial(sac "SAC scheme")
same_log_tail(sac_serial sac_ranks ",complexes,mean_adsorbed" 1 "SAC scheme")

# Split displacements (free draining): the parts are the serial engine's bit for bit and rank 0
# sums their squares in global index order, so the log's deterministic_rms and brownian_rms columns
# (its last two) are the serial run's character for character (the other columns hold timings).
string(REPLACE "seed = 11" "seed = 11\nsplit_displacements = true" split "${text}")
file(WRITE "${WORK}/split.toml" "${split}")
run_bd(0 --config "${WORK}/split.toml" --out-dir "${WORK}/split_serial" --quiet)
run_bd(${NP} --config "${WORK}/split.toml" --out-dir "${WORK}/split_ranks" --quiet)
same_trajectory(split_serial split_ranks "split displacements, 60 steps on ${NP} ranks")
# rows from step 10 (the row of step 0 has no step behind it)
same_log_tail(split_serial split_ranks ",deterministic_rms,brownian_rms" 2 "split displacements")

# Bead-spring chains (harmonic bonds, WCA pairs): the bonds' partners travel with the halo, and the
# trajectory is the serial run's byte for byte.
string(REPLACE "source = \"random\"\ncount = 600" "source = \"chains\"\nchains = 20\nbeads = 10" chains "${text}")
file(WRITE "${WORK}/chains.toml" "${chains}\n[bonds]\nkind = \"harmonic\"\nk = 100.0\nlength = 1.0\n")
run_bd(0 --config "${WORK}/chains.toml" --out-dir "${WORK}/chains_serial" --quiet)
run_bd(${NP} --config "${WORK}/chains.toml" --out-dir "${WORK}/chains_ranks" --quiet)
same_trajectory(chains_serial chains_ranks "chains, 60 steps on ${NP} ranks")

# Refused configurations: every rank fails, rank 0 prints one line, nothing is left behind.
string(REPLACE "method = \"none\"" "method = \"direct\"" direct "${text}")
file(WRITE "${WORK}/direct.toml" "${direct}")
string(REPLACE "wave_precision = \"double\"" "wave_precision = \"single\"" single "${pse}")
file(WRITE "${WORK}/single.toml" "${single}")
include("${CMAKE_CURRENT_LIST_DIR}/expect_one_error.cmake")
foreach(case "direct;a periodic box needs pse" "single;wave_precision = \"single\" is not run across ranks")
  list(GET case 0 name)
  list(GET case 1 expected)
  expect_one_error("bd ${name}" "${expected}" "${WORK}/never_${name}" "${RPYFMM}" bd --config "${WORK}/${name}.toml"
                   --out-dir "${WORK}/never_${name}" --quiet)
endforeach()
file(REMOVE_RECURSE "${WORK}")

# `mpiexec -n NP rpyfmm bd` against the serial command on the same configuration (docs/mpi.md,
# "Brownian dynamics across ranks"). With free draining the positions after every step are the
# serial engine's bit for bit, so the trajectory files must be identical byte for byte:
#  - a run of 60 steps on NP ranks (frames every 10, a checkpoint every 30);
#  - the first 30 steps on 2 ranks, then a restart from their checkpoint on NP ranks.
# A configuration the ranks do not run (method pse; bonds) fails every rank: exit status 2, one
# error line, no output directory. Run by ctest as
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

run_bd(0 --config "${WORK}/run.toml" --out-dir "${WORK}/serial" --quiet)
run_bd(${NP} --config "${WORK}/run.toml" --out-dir "${WORK}/ranks" --json)
if(NOT run_output MATCHES "\"ranks\":${NP}" OR NOT run_output MATCHES "\"last_step\":60")
  message(FATAL_ERROR "--json across ${NP} ranks: ${run_output}")
endif()
same_trajectory(serial ranks "60 steps on ${NP} ranks")
run_bd(2 --config "${WORK}/run.toml" --out-dir "${WORK}/restarted" --steps 30 --quiet)
run_bd(${NP} --restart "${WORK}/restarted/checkpoint.bin" --quiet)
same_trajectory(serial restarted "30 steps on 2 ranks, 30 more on ${NP}")

# Refused configurations: every rank fails, rank 0 prints one line, nothing is left behind.
file(READ "${WORK}/run.toml" text)
string(REPLACE "method = \"none\"" "method = \"pse\"" pse "${text}")
file(WRITE "${WORK}/pse.toml" "${pse}")
string(REPLACE "source = \"random\"\ncount = 600" "source = \"chains\"\nchains = 20\nbeads = 10" chains "${text}")
file(WRITE "${WORK}/chains.toml" "${chains}\n[bonds]\nkind = \"harmonic\"\nk = 100.0\nlength = 1.0\n")
foreach(case "pse;method 'pse' is not run across ranks" "chains;bonds are not supported across ranks")
  list(GET case 0 name)
  list(GET case 1 expected)
  execute_process(COMMAND "${MPIEXEC}" -n ${NP} ${flags} "${RPYFMM}" bd --config "${WORK}/${name}.toml"
                          --out-dir "${WORK}/never_${name}" --quiet
                  RESULT_VARIABLE rc ERROR_VARIABLE err)
  string(REGEX MATCHALL "rpyfmm: error:" errors "${err}")
  list(LENGTH errors count)
  if(NOT rc EQUAL 2 OR NOT count EQUAL 1 OR NOT err MATCHES "${expected}" OR EXISTS "${WORK}/never_${name}")
    message(FATAL_ERROR "bd ${name} under ${NP} ranks: exit ${rc}, ${count} error lines: ${err}")
  endif()
endforeach()
file(REMOVE_RECURSE "${WORK}")

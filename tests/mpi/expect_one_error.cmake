# expect_one_error(NAME PATTERN OUTPUT COMMAND...): runs COMMAND under ${MPIEXEC} -n ${NP} ${flags}
# and requires the collective failure of the command-line tool across ranks (docs/mpi.md, "The
# command-line tool"): exit status 2, exactly one error line (printed by rank 0) matching PATTERN,
# and nothing at OUTPUT (a file or folder the command would have written). Included by
# cli_across_ranks.cmake and bd_across_ranks.cmake.
function(expect_one_error name pattern output)
  execute_process(COMMAND "${MPIEXEC}" -n ${NP} ${flags} ${ARGN} RESULT_VARIABLE rc ERROR_VARIABLE err)
  string(REGEX MATCHALL "rpyfmm: error:" errors "${err}")
  list(LENGTH errors count)
  if(NOT rc EQUAL 2 OR NOT count EQUAL 1 OR NOT err MATCHES "${pattern}" OR EXISTS "${output}")
    message(FATAL_ERROR "${name} under ${NP} ranks: exit ${rc}, ${count} error lines: ${err}")
  endif()
endfunction()

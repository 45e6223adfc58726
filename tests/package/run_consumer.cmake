# Script mode: installs this build into a scratch prefix (PREFIX), configures and builds an outside
# project against it with find_package (CONSUMER_SRC into CONSUMER_BUILD), and runs its executable
# EXECUTABLE (default: consumer). Used by package.find_package_consumer (tests/package) and
# mpi.package.find_package_consumer (tests/mpi), which passes MPIEXEC (and MPI_FLAGS) to run the
# executable under mpiexec on 2 ranks. The scratch folders are removed after a success.
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "command failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  message(STATUS "${out}")
endfunction()
if(NOT DEFINED EXECUTABLE)
  set(EXECUTABLE consumer)
endif()
set(launcher "")
if(DEFINED MPIEXEC)
  separate_arguments(flags UNIX_COMMAND "${MPI_FLAGS}")
  set(launcher ${MPIEXEC} -n 2 ${flags})
endif()
file(REMOVE_RECURSE ${PREFIX} ${CONSUMER_BUILD})
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${PREFIX})
run(${CMAKE_COMMAND} -S ${CONSUMER_SRC} -B ${CONSUMER_BUILD} -G ${GENERATOR} -DCMAKE_PREFIX_PATH=${PREFIX}
    -DCMAKE_BUILD_TYPE=Release "-DCMAKE_CXX_FLAGS=${CXX_FLAGS}" "-DCMAKE_EXE_LINKER_FLAGS=${LINKER_FLAGS}")
run(${CMAKE_COMMAND} --build ${CONSUMER_BUILD})
run(${launcher} ${CONSUMER_BUILD}/${EXECUTABLE})
file(REMOVE_RECURSE ${PREFIX} ${CONSUMER_BUILD})

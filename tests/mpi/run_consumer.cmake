# Script mode (ctest mpi.package.find_package_consumer): installs this build into a scratch prefix,
# configures and builds tests/mpi/consumer against it with find_package(rpyfmm COMPONENTS mpi), and
# runs the consumer under mpiexec on 2 ranks.
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "command failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  message(STATUS "${out}")
endfunction()
separate_arguments(flags UNIX_COMMAND "${MPI_FLAGS}")
file(REMOVE_RECURSE ${PREFIX} ${CONSUMER_BUILD})
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${PREFIX})
run(${CMAKE_COMMAND} -S ${CONSUMER_SRC} -B ${CONSUMER_BUILD} -G ${GENERATOR} -DCMAKE_PREFIX_PATH=${PREFIX}
    -DCMAKE_BUILD_TYPE=Release "-DCMAKE_CXX_FLAGS=${CXX_FLAGS}" "-DCMAKE_EXE_LINKER_FLAGS=${LINKER_FLAGS}")
run(${CMAKE_COMMAND} --build ${CONSUMER_BUILD})
run(${MPIEXEC} -n 2 ${flags} ${CONSUMER_BUILD}/mpi_consumer)
file(REMOVE_RECURSE ${PREFIX} ${CONSUMER_BUILD})

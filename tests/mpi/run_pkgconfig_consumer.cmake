# Script mode (ctest mpi.package.pkg_config_consumer): installs this build into PREFIX, compiles and
# links tests/mpi/consumer with nothing but `pkg-config --cflags --libs rpyfmm-mpi` (the MPI
# layer's module, cmake/RpyfmmPkgConfig.cmake) and runs it under MPIEXEC on 2 ranks. Any failing
# step stops the script (COMMAND_ERROR_IS_FATAL).
cmake_minimum_required(VERSION 3.20)
file(REMOVE_RECURSE ${PREFIX} ${OUT_DIR})
file(MAKE_DIRECTORY ${OUT_DIR})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${PREFIX} OUTPUT_QUIET
                COMMAND_ERROR_IS_FATAL ANY)
file(GLOB_RECURSE pc_file ${PREFIX}/*/rpyfmm-mpi.pc)
if(NOT pc_file)
  message(FATAL_ERROR "no rpyfmm-mpi.pc installed under ${PREFIX}")
endif()
get_filename_component(pc_dir "${pc_file}" DIRECTORY)
set(ENV{PKG_CONFIG_PATH} "${pc_dir}")
execute_process(COMMAND ${PKG_CONFIG} --modversion rpyfmm-mpi OUTPUT_VARIABLE version
                OUTPUT_STRIP_TRAILING_WHITESPACE COMMAND_ERROR_IS_FATAL ANY)
if(NOT version STREQUAL VERSION)
  message(FATAL_ERROR "pkg-config reports rpyfmm-mpi ${version}, the project is ${VERSION}")
endif()
execute_process(COMMAND ${PKG_CONFIG} --cflags --libs rpyfmm-mpi OUTPUT_VARIABLE pc_flags
                OUTPUT_STRIP_TRAILING_WHITESPACE COMMAND_ERROR_IS_FATAL ANY)
message(STATUS "pkg-config --cflags --libs rpyfmm-mpi: ${pc_flags}")
separate_arguments(pc_flags UNIX_COMMAND "${pc_flags}")
separate_arguments(cxx_flags UNIX_COMMAND "${CXX_FLAGS} ${LINKER_FLAGS}")
separate_arguments(mpi_flags UNIX_COMMAND "${MPI_FLAGS}")
execute_process(COMMAND ${CXX} -std=c++20 ${cxx_flags} ${CONSUMER_SRC}/main.cpp -o ${OUT_DIR}/mpi_consumer ${pc_flags}
                COMMAND_ERROR_IS_FATAL ANY)
execute_process(COMMAND ${MPIEXEC} -n 2 ${mpi_flags} ${OUT_DIR}/mpi_consumer COMMAND_ERROR_IS_FATAL ANY)
file(REMOVE_RECURSE ${PREFIX} ${OUT_DIR})

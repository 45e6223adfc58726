# The optional MPI layer (mpi/, docs/mpi.md): RPYFMM_USE_MPI is on by default where an MPI C++
# environment is found (Debian: libopenmpi-dev), off otherwise; with it off, nothing here changes
# the build. Only MPI's C interface is used: its deprecated C++ bindings are skipped.
if(NOT DEFINED RPYFMM_USE_MPI OR RPYFMM_USE_MPI)
  set(MPI_CXX_SKIP_MPICXX ON)
  find_package(MPI COMPONENTS CXX QUIET)
endif()
# MPI_CXX_FOUND is TRUE, FALSE, or unset where the option was set OFF before (then unused).
option(RPYFMM_USE_MPI "Build the MPI layer rpyfmm::mpi (default: on when MPI is found)" "${MPI_CXX_FOUND}")
if(RPYFMM_USE_MPI AND NOT MPI_CXX_FOUND)
  message(FATAL_ERROR "RPYFMM_USE_MPI is ON but no MPI C++ environment was found "
                      "(Debian: apt-get install libopenmpi-dev openmpi-bin), or configure with -DRPYFMM_USE_MPI=OFF")
endif()

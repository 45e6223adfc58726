# The optional MPI layer (mpi/, docs/mpi.md): RPYFMM_USE_MPI is on by default where an MPI C++
# environment is found (Debian: libopenmpi-dev), off otherwise; with it off, nothing here changes
# the build. Only MPI's C interface is used: its deprecated C++ bindings are skipped.
# The layer's distributed PSE needs FFTW's MPI transforms (Debian: libfftw3-mpi-dev) beside MPI.
set(_rpyfmm_mpi_found FALSE)
if(NOT DEFINED RPYFMM_USE_MPI OR RPYFMM_USE_MPI)
  set(MPI_CXX_SKIP_MPICXX ON)
  find_package(MPI COMPONENTS CXX QUIET)
  find_library(FFTW3_MPI_LIBRARY NAMES fftw3_mpi)
  find_path(FFTW3_MPI_INCLUDE_DIR NAMES fftw3-mpi.h)
  if(MPI_CXX_FOUND AND FFTW3_MPI_LIBRARY AND FFTW3_MPI_INCLUDE_DIR)
    set(_rpyfmm_mpi_found TRUE)
  endif()
endif()
option(RPYFMM_USE_MPI "Build the MPI layer rpyfmm::mpi (default: on when MPI and FFTW-MPI are found)"
       "${_rpyfmm_mpi_found}")
if(RPYFMM_USE_MPI AND NOT MPI_CXX_FOUND)
  message(FATAL_ERROR "RPYFMM_USE_MPI is ON but no MPI C++ environment was found "
                      "(Debian: apt-get install libopenmpi-dev openmpi-bin), or configure with -DRPYFMM_USE_MPI=OFF")
endif()
if(RPYFMM_USE_MPI AND NOT (FFTW3_MPI_LIBRARY AND FFTW3_MPI_INCLUDE_DIR))
  message(FATAL_ERROR "RPYFMM_USE_MPI is ON but FFTW's MPI library (fftw3_mpi, fftw3-mpi.h) was not found "
                      "(Debian: apt-get install libfftw3-mpi-dev), or configure with -DRPYFMM_USE_MPI=OFF")
endif()

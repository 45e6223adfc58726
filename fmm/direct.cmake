# Direct O(N^2) Laplace kernels (also the FMM's P2P).
target_sources(rpyfmm_fmm PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/version.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/direct_laplace.cpp)
# sqrt must not set errno, or GCC keeps it scalar (a libm call per pair) and the
# pair loops do not vectorize. The kernels never read errno.
set_source_files_properties(${CMAKE_CURRENT_LIST_DIR}/src/direct_laplace.cpp
  PROPERTIES COMPILE_OPTIONS "-fno-math-errno")

# Direct O(N^2) Laplace kernels (also the FMM's P2P).
target_sources(rpyfmm_fmm PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/version.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/direct_laplace.cpp)
# Branch-free pair loops: see cmake/RpyfmmPairLoops.cmake.
rpyfmm_vectorize_pair_loops(${CMAKE_CURRENT_LIST_DIR}/src/direct_laplace.cpp)

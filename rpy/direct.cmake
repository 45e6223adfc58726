# RPY pair formulas (header-only rpy_kernel.hpp) and the direct O(N^2) operator.
target_sources(rpyfmm_rpy PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/direct_operator.cpp)
# Branch-free pair loops: see cmake/RpyfmmPairLoops.cmake.
rpyfmm_vectorize_pair_loops(${CMAKE_CURRENT_LIST_DIR}/src/direct_operator.cpp)

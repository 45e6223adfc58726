# RPY pair formulas (header-only rpy_kernel.hpp), the direct O(N^2) operator, and the length units
# and rotational pair sums shared with the FMM operator.
target_sources(rpyfmm_rpy PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/direct_operator.cpp
                                  ${CMAKE_CURRENT_LIST_DIR}/src/length_units.cpp
                                  ${CMAKE_CURRENT_LIST_DIR}/src/direct_rotation.cpp
                                  ${CMAKE_CURRENT_LIST_DIR}/src/rotation_pair_sums.cpp)
# Branch-free pair loops: see cmake/RpyfmmPairLoops.cmake.
rpyfmm_vectorize_pair_loops(${CMAKE_CURRENT_LIST_DIR}/src/direct_operator.cpp
                            ${CMAKE_CURRENT_LIST_DIR}/src/rotation_pair_sums.cpp)

# FMM-backed free-space RPY operator (FmmRpy).
target_sources(rpyfmm_rpy PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/fmm_operator.cpp
                                  ${CMAKE_CURRENT_LIST_DIR}/src/fmm_far_field.cpp
                                  ${CMAKE_CURRENT_LIST_DIR}/src/fmm_laplace_accuracy.cpp
                                  ${CMAKE_CURRENT_LIST_DIR}/src/fmm_leaf_rules.cpp
                                  ${CMAKE_CURRENT_LIST_DIR}/src/fmm_near_field.cpp
                                  ${CMAKE_CURRENT_LIST_DIR}/src/fmm_near_kernels.cpp
                                  ${CMAKE_CURRENT_LIST_DIR}/src/fmm_rotation.cpp
                                  ${CMAKE_CURRENT_LIST_DIR}/src/near_schedule.cpp)
# Branch-free pair loops: see cmake/RpyfmmPairLoops.cmake.
rpyfmm_vectorize_pair_loops(${CMAKE_CURRENT_LIST_DIR}/src/fmm_near_kernels.cpp)

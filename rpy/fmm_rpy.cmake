# FMM-backed free-space RPY operator (FmmRpy).
target_sources(rpyfmm_rpy PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/fmm_operator.cpp
                                  ${CMAKE_CURRENT_LIST_DIR}/src/fmm_near_kernels.cpp)
# sqrt must not set errno, or the near-field pair loop does not vectorize.
set_source_files_properties(${CMAKE_CURRENT_LIST_DIR}/src/fmm_near_kernels.cpp PROPERTIES COMPILE_OPTIONS "-fno-math-errno")

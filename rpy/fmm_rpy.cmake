# FMM-backed free-space RPY operator (FmmRpy).
target_sources(rpyfmm_rpy PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/fmm_operator.cpp)

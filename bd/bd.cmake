# Sources of rpyfmm::bd.
target_sources(rpyfmm_bd PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/sampling.cpp)

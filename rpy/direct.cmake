# RPY pair formulas (header-only rpy_kernel.hpp) and the direct O(N^2) operator.
target_sources(rpyfmm_rpy PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/direct_operator.cpp)
# sqrt must not set errno, or the pair loops do not vectorize (see fmm/direct.cmake).
set_source_files_properties(${CMAKE_CURRENT_LIST_DIR}/src/direct_operator.cpp
  PROPERTIES COMPILE_OPTIONS "-fno-math-errno")

# Adaptive octree FMM: tree, lists, expansions, plane-wave M2L, driver.
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
target_sources(rpyfmm_fmm PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/harmonics.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/point_expansions.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/simd_expansions.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/rotation.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/child_translations.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/planewave_tables.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/planewave.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/planewave_batch.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/planewave_kernels.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/octree.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/leaf_grid.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/fmm_passes.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/plane_wave_m2l.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/laplace_fmm.cpp)
target_link_libraries(rpyfmm_fmm PRIVATE Eigen3::Eigen)
# std::complex products without the C99 Annex G inf/nan recovery (__muldc3): every value here is finite.
set_source_files_properties(
  ${CMAKE_CURRENT_LIST_DIR}/src/harmonics.cpp ${CMAKE_CURRENT_LIST_DIR}/src/point_expansions.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/rotation.cpp ${CMAKE_CURRENT_LIST_DIR}/src/child_translations.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/planewave.cpp ${CMAKE_CURRENT_LIST_DIR}/src/planewave_batch.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/fmm_passes.cpp ${CMAKE_CURRENT_LIST_DIR}/src/plane_wave_m2l.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/laplace_fmm.cpp
  PROPERTIES COMPILE_OPTIONS "-fcx-limited-range")

# Rigid bodies of beads: the body mobility by preconditioned GMRES — see
# rpy/include/rpyfmm/rpy/rigid_bodies.hpp.
target_sources(rpyfmm_rpy PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/rigid/bead_shapes.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/rigid/body_system.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/rigid/gmres.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/rigid/mobility_matrix.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/rigid/rigid_bodies.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/rigid/saddle_point.cpp)

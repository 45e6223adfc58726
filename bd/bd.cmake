# Sources of rpyfmm::bd (owner: bd).
target_sources(rpyfmm_bd PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/sampling.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/rotation_sampling.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/quaternion.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/torque_field.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/potentials.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/force_field.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/neighbour_list.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/integrator.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/rigid_dynamics.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/checkpoint.cpp)
target_sources(rpyfmm_bd PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/config.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/particles.cpp)
target_sources(rpyfmm_bd PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/output.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/run.cpp)

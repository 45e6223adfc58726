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
  ${CMAKE_CURRENT_LIST_DIR}/src/langevin.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/langevin_group.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/sac.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/rigid_dynamics.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/checkpoint.cpp)
target_sources(rpyfmm_bd PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/config.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/particles.cpp)
target_sources(rpyfmm_bd PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/output.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/hoomd_frame.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/trajectory.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/run.cpp)
# GSD trajectories: gsd's C library compiled into rpyfmm::bd where cmake/RpyfmmGsd.cmake found it.
if(RPYFMM_HAVE_GSD)
  target_sources(rpyfmm_bd PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/gsd_trajectory.cpp $<TARGET_OBJECTS:rpyfmm_gsd>)
  target_include_directories(rpyfmm_bd PRIVATE $<BUILD_INTERFACE:${RPYFMM_GSD_INCLUDE_DIR}>)
else()
  target_sources(rpyfmm_bd PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/gsd_unavailable.cpp)
endif()

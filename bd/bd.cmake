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
  ${CMAKE_CURRENT_LIST_DIR}/src/integrator_device.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/step_engine.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/langevin.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/langevin_group.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/sac.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/rigid_dynamics.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/rigid/rigid_stages.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/checkpoint.cpp)
target_sources(rpyfmm_bd PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/config.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/particles.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/particle_spec.cpp)
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
# BD stages as host-device functions (bd/src/device, docs/gpu-bd.md): the host launcher always,
# the CUDA engine where RPYFMM_USE_CUDA. The launcher keeps a * b + c unfused, as nvcc's
# --fmad=false keeps the kernels, so that host and device compute the same bits.
target_sources(rpyfmm_bd PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/device/engine_tables.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/device/step_status.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/device/device_support.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/device/device_stepper.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/device/host_engine.cpp)
set_source_files_properties(${CMAKE_CURRENT_LIST_DIR}/src/device/host_engine.cpp PROPERTIES
  COMPILE_OPTIONS "$<$<CXX_COMPILER_ID:GNU,Clang>:-ffp-contract=off>")
if(RPYFMM_USE_CUDA)
  target_sources(rpyfmm_bd PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/device/device_engine.cu)
  target_link_libraries(rpyfmm_bd PRIVATE CUDA::cudart)
  # As rpy/pse.cmake: -std=c++20 passed directly (CMake 3.25 lacks nvcc's C++20 dialect).
  set_target_properties(rpyfmm_bd PROPERTIES CUDA_SEPARABLE_COMPILATION OFF CUDA_STANDARD_REQUIRED OFF)
  set_property(TARGET rpyfmm_bd PROPERTY CUDA_STANDARD)
  target_compile_options(rpyfmm_bd PRIVATE
    $<$<COMPILE_LANGUAGE:CUDA>:-std=c++20 --expt-relaxed-constexpr --fmad=false -lineinfo>)
else()
  target_sources(rpyfmm_bd PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/device/device_engine_unavailable.cpp)
endif()

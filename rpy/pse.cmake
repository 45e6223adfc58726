# sources for rpy/pse (see rpy/CMakeLists.txt): periodic RPY by Positively
# Split Ewald. CPU (FFTW + OpenMP) always; the CUDA backend when RPYFMM_USE_CUDA.
target_sources(rpyfmm_rpy PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/parameters.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/real_space.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/rotation_real_space.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/real_space_sum.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/rotation_real_space_sum.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/real_space_apply.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/neighbour_lists.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/list_filter.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/half_blocks.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/pair_cache.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/pair_rows.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/pair_rows_avx512.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/wave_space.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/scale_line.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/window_avx2.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/window_avx512.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/pse_rpy.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/pse/open_pse_rpy.cpp)
# The line loop's sqrt and selects vectorize only without errno and FP traps (no value changes).
set_source_files_properties(${CMAKE_CURRENT_LIST_DIR}/src/pse/scale_line.cpp PROPERTIES
  COMPILE_OPTIONS "$<$<CXX_COMPILER_ID:GNU,Clang>:-fno-trapping-math;-fno-math-errno>")
target_link_libraries(rpyfmm_rpy PRIVATE PkgConfig::FFTW3 ${FFTW3_OMP_LIBRARY} PkgConfig::FFTW3F ${FFTW3F_OMP_LIBRARY})

# The rotational real-space rows: branch-free pair loops (cmake/RpyfmmPairLoops.cmake).
rpyfmm_vectorize_pair_loops(${CMAKE_CURRENT_LIST_DIR}/src/pse/rotation_real_space_sum.cpp)
if(RPYFMM_USE_CUDA)
  target_sources(rpyfmm_rpy PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/pse/pse_rpy_cuda.cu
                                    ${CMAKE_CURRENT_LIST_DIR}/src/pse/device_checks.cu
                                    ${CMAKE_CURRENT_LIST_DIR}/src/pse/host_copy.cpp)
  target_link_libraries(rpyfmm_rpy PRIVATE CUDA::cufft CUDA::cudart)
  target_compile_definitions(rpyfmm_rpy PUBLIC RPYFMM_HAVE_CUDA_PSE=1)
  # CMake < 3.26 does not know nvcc's C++20 flag (CMAKE_CUDA_STANDARD 20 fails at generate
  # time): drop the target's CUDA standard property and pass -std=c++20 directly.
  set_target_properties(rpyfmm_rpy PROPERTIES CUDA_SEPARABLE_COMPILATION OFF CUDA_STANDARD_REQUIRED OFF)
  set_property(TARGET rpyfmm_rpy PROPERTY CUDA_STANDARD)
  target_compile_options(rpyfmm_rpy PRIVATE $<$<COMPILE_LANGUAGE:CUDA>:-std=c++20>)
  # Random123 headers trip nvcc's host-compiler warnings; keep the CUDA flags quiet and fast.
  target_compile_options(rpyfmm_rpy PRIVATE $<$<COMPILE_LANGUAGE:CUDA>:--expt-relaxed-constexpr -lineinfo>)
else()
  target_sources(rpyfmm_rpy PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/pse/pse_rpy_cuda_stub.cpp)
endif()

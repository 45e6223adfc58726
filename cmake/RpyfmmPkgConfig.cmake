# rpyfmm.pc for consumers without CMake: `pkg-config --cflags --libs rpyfmm` compiles and links
# against an installed rpyfmm (tests/package: package.pkg_config_consumer).
#
# The libraries are static archives, so their dependencies go into Libs and Requires (not the
# .private fields): FFTW (double and single, with their OpenMP variants), OpenMP, and the CUDA
# runtime and cuFFT in a CUDA build; the public compile definitions go into Cflags. A module that
# gains a link dependency adds it here. The headers need C++20 (-std=c++20), which is the
# consumer's compiler setting and not in Cflags.

# prefix relative to the .pc file's folder (<prefix>/<libdir>/pkgconfig), so the tree is relocatable
# and `cmake --install --prefix P` works with the prefix chosen at install time.
if(IS_ABSOLUTE "${CMAKE_INSTALL_LIBDIR}" OR IS_ABSOLUTE "${CMAKE_INSTALL_INCLUDEDIR}")
  set(RPYFMM_PC_PREFIX "${CMAKE_INSTALL_PREFIX}")
  set(RPYFMM_PC_LIBDIR "${CMAKE_INSTALL_FULL_LIBDIR}")
  set(RPYFMM_PC_INCLUDEDIR "${CMAKE_INSTALL_FULL_INCLUDEDIR}")
else()
  file(RELATIVE_PATH _rpyfmm_pc_up "/root/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/root")  # ../.. for lib
  string(REGEX REPLACE "/$" "" _rpyfmm_pc_up "${_rpyfmm_pc_up}")
  set(RPYFMM_PC_PREFIX "\${pcfiledir}/${_rpyfmm_pc_up}")
  set(RPYFMM_PC_LIBDIR "\${prefix}/${CMAKE_INSTALL_LIBDIR}")
  set(RPYFMM_PC_INCLUDEDIR "\${prefix}/${CMAKE_INSTALL_INCLUDEDIR}")
endif()

set(RPYFMM_PC_REQUIRES "fftw3 fftw3f")
set(_rpyfmm_pc_libs "")
foreach(_lib IN ITEMS ${FFTW3_OMP_LIBRARY} ${FFTW3F_OMP_LIBRARY})
  get_filename_component(_name "${_lib}" NAME_WE)  # /usr/lib/.../libfftw3_omp.so -> libfftw3_omp
  string(REGEX REPLACE "^lib" "" _name "${_name}")
  list(APPEND _rpyfmm_pc_libs "-l${_name}")
endforeach()
set(_rpyfmm_pc_cflags ${OpenMP_CXX_FLAGS})
list(APPEND _rpyfmm_pc_libs ${OpenMP_CXX_FLAGS})
# The modules' public compile definitions (RPYFMM_NO_X86_KERNELS, RPYFMM_HAVE_CUDA_PSE, ...).
foreach(_target IN ITEMS rpyfmm_core rpyfmm_fmm rpyfmm_rpy rpyfmm_bd)
  get_target_property(_defs ${_target} INTERFACE_COMPILE_DEFINITIONS)
  foreach(_def IN LISTS _defs)
    if(_def AND NOT _def MATCHES "\\$<")
      list(APPEND _rpyfmm_pc_cflags "-D${_def}")
    endif()
  endforeach()
endforeach()
if(RPYFMM_USE_CUDA)
  list(APPEND _rpyfmm_pc_libs "-L${CUDAToolkit_LIBRARY_DIR}" "-Wl,-rpath,${CUDAToolkit_LIBRARY_DIR}" -lcufft -lcudart)
endif()
list(JOIN _rpyfmm_pc_cflags " " RPYFMM_PC_CFLAGS)
list(JOIN _rpyfmm_pc_libs " " RPYFMM_PC_LIBS)

configure_file(${CMAKE_CURRENT_LIST_DIR}/rpyfmm.pc.in ${CMAKE_CURRENT_BINARY_DIR}/rpyfmm.pc @ONLY)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/rpyfmm.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

# Square-root solvers (Lanczos, Chebyshev, dense) — see rpy/include/rpyfmm/rpy/sqrt.hpp.
target_sources(rpyfmm_rpy PRIVATE
  ${CMAKE_CURRENT_LIST_DIR}/src/sqrt/sqrt_apply.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/sqrt/kernels.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/sqrt/krylov.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/sqrt/lanczos.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/sqrt/chebyshev.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/sqrt/dense.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/sqrt/block_factors.cpp
  ${CMAKE_CURRENT_LIST_DIR}/src/sqrt/block_preconditioner.cpp)

# Square-root solvers (Lanczos, Chebyshev, dense) — see rpy/include/rpyfmm/rpy/sqrt.hpp.
target_sources(rpyfmm_rpy PRIVATE ${CMAKE_CURRENT_LIST_DIR}/src/sqrt/sqrt_apply.cpp)

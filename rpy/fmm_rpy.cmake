# sources for rpy/fmm_rpy (see rpy/CMakeLists.txt)

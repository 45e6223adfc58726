# sources for rpy/pse (see rpy/CMakeLists.txt)

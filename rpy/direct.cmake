# sources for rpy/direct (see rpy/CMakeLists.txt)

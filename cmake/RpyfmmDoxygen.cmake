# The `docs` target: the API reference, Doxygen over the public headers
# (<module>/include/rpyfmm/**; mpi/include/rpyfmm where the MPI layer is built), written to
# <build>/docs/html. Any Doxygen warning (an undocumented
# parameter name, a broken \ref, malformed markup) fails the build (WARN_AS_ERROR =
# FAIL_ON_WARNINGS: every warning is listed, then the target fails). The target exists only where
# Doxygen is installed (Debian package `doxygen`, scripts/install-deps.sh).
find_package(Doxygen)
if(NOT DOXYGEN_FOUND)
  message(STATUS "rpyfmm API reference: Doxygen not found, no `docs` target")
  return()
endif()

set(DOXYGEN_PROJECT_NAME "rpyfmm")
set(DOXYGEN_PROJECT_BRIEF "${PROJECT_DESCRIPTION}")
set(DOXYGEN_OUTPUT_DIRECTORY "${PROJECT_BINARY_DIR}/docs")
set(DOXYGEN_GENERATE_HTML YES)
set(DOXYGEN_GENERATE_LATEX NO)
set(DOXYGEN_EXTRACT_ALL YES)
set(DOXYGEN_RECURSIVE YES)
set(DOXYGEN_FILE_PATTERNS "*.hpp")
# Paths relative to the repository in the file list, so that headers of different modules with
# the same name stay apart.
set(DOXYGEN_FULL_PATH_NAMES YES)
set(DOXYGEN_STRIP_FROM_PATH "${PROJECT_SOURCE_DIR}")
set(_rpyfmm_doc_modules core fmm rpy bd)
if(RPYFMM_USE_MPI)
  list(APPEND _rpyfmm_doc_modules mpi)
endif()
set(_rpyfmm_doc_include_dirs ${_rpyfmm_doc_modules})
list(TRANSFORM _rpyfmm_doc_include_dirs APPEND /include)
set(DOXYGEN_STRIP_FROM_INC_PATH ${_rpyfmm_doc_include_dirs})
# `#include "rpyfmm/..."` resolves against the module include folders; macros are expanded so
# that host/device qualifiers do not hide declarations.
set(DOXYGEN_ENABLE_PREPROCESSING YES)
set(DOXYGEN_MACRO_EXPANSION YES)
set(DOXYGEN_PREDEFINED "RPYFMM_HOST_DEVICE=" "__CUDACC__=0")
set(DOXYGEN_INCLUDE_PATH ${_rpyfmm_doc_include_dirs})
set(DOXYGEN_WARN_IF_UNDOCUMENTED NO)
set(DOXYGEN_WARN_AS_ERROR FAIL_ON_WARNINGS)
set(DOXYGEN_QUIET YES)
set(DOXYGEN_HAVE_DOT NO)
set(DOXYGEN_USE_MDFILE_AS_MAINPAGE "${PROJECT_SOURCE_DIR}/docs/api.md")

set(_rpyfmm_doc_inputs ${_rpyfmm_doc_include_dirs})
list(TRANSFORM _rpyfmm_doc_inputs REPLACE "(.+)" "${PROJECT_SOURCE_DIR}/\\1/rpyfmm")
doxygen_add_docs(docs
  "${PROJECT_SOURCE_DIR}/docs/api.md"
  ${_rpyfmm_doc_inputs}
  WORKING_DIRECTORY "${PROJECT_SOURCE_DIR}"
  COMMENT "API reference (Doxygen over the public headers, warnings are errors)")

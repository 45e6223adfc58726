# GSD trajectories (HOOMD-blue's binary format) through the C library of the `gsd` package
# (gsd/gsd.c and gsd/gsd.h, BSD-2-Clause), compiled from its source distribution. The repository
# carries none of it: scripts/fetch-gsd.sh (run by scripts/install-deps.sh) unpacks the pinned
# sdist, checksum-verified, into a directory outside the repository, and this file finds it there.
#
#   RPYFMM_WITH_GSD        OFF builds without GSD even where the sources are found (default ON)
#   RPYFMM_GSD_SOURCE_DIR  root of an unpacked gsd source distribution (the directory holding
#                          gsd/gsd.c); empty: $ENV{RPYFMM_GSD_SOURCE_DIR}, then where
#                          scripts/fetch-gsd.sh puts it (/usr/local/src/gsd-<version> as root,
#                          ${XDG_CACHE_HOME:-~/.cache}/rpyfmm/gsd-<version> otherwise).
#
# Found: the OBJECT library rpyfmm_gsd (gsd.c, C11) and RPYFMM_HAVE_GSD = ON. Not found: the
# build goes on without it; rpyfmm::bd then refuses `[output] format = "gsd"` naming why.
option(RPYFMM_WITH_GSD "GSD trajectories through gsd's C library, where its sources are found" ON)
set(RPYFMM_GSD_VERSION 5.0.1)
set(RPYFMM_GSD_SOURCE_DIR "" CACHE PATH
    "Root of an unpacked gsd ${RPYFMM_GSD_VERSION} source distribution (holds gsd/gsd.c); empty: the default places")

set(_rpyfmm_gsd_places "")
if(RPYFMM_GSD_SOURCE_DIR)
  set(_rpyfmm_gsd_places ${RPYFMM_GSD_SOURCE_DIR})
else()
  if(DEFINED ENV{RPYFMM_GSD_SOURCE_DIR})
    list(APPEND _rpyfmm_gsd_places $ENV{RPYFMM_GSD_SOURCE_DIR})
  endif()
  list(APPEND _rpyfmm_gsd_places /usr/local/src/gsd-${RPYFMM_GSD_VERSION})
  if(DEFINED ENV{XDG_CACHE_HOME})
    list(APPEND _rpyfmm_gsd_places $ENV{XDG_CACHE_HOME}/rpyfmm/gsd-${RPYFMM_GSD_VERSION})
  endif()
  if(DEFINED ENV{HOME})
    list(APPEND _rpyfmm_gsd_places $ENV{HOME}/.cache/rpyfmm/gsd-${RPYFMM_GSD_VERSION})
  endif()
endif()

# Searched anew at every configure until found (an unfound path is not cached), so installing the
# sources and re-running cmake enables GSD.
unset(_rpyfmm_gsd_root)
if(NOT RPYFMM_WITH_GSD)
  set(_rpyfmm_gsd_places "")
endif()
foreach(_place IN LISTS _rpyfmm_gsd_places)
  if(EXISTS ${_place}/gsd/gsd.c AND EXISTS ${_place}/gsd/gsd.h)
    set(_rpyfmm_gsd_root ${_place})
    break()
  endif()
endforeach()

if(NOT _rpyfmm_gsd_root AND RPYFMM_GSD_SOURCE_DIR AND RPYFMM_WITH_GSD)
  message(FATAL_ERROR "RPYFMM_GSD_SOURCE_DIR='${RPYFMM_GSD_SOURCE_DIR}' has no gsd/gsd.c and gsd/gsd.h")
endif()

if(_rpyfmm_gsd_root)
  set(RPYFMM_HAVE_GSD ON)
  enable_language(C)
  add_library(rpyfmm_gsd OBJECT ${_rpyfmm_gsd_root}/gsd/gsd.c)
  target_include_directories(rpyfmm_gsd PUBLIC $<BUILD_INTERFACE:${_rpyfmm_gsd_root}/gsd>)
  set_target_properties(rpyfmm_gsd PROPERTIES C_STANDARD 11 C_STANDARD_REQUIRED ON POSITION_INDEPENDENT_CODE ON)
  set(RPYFMM_GSD_INCLUDE_DIR ${_rpyfmm_gsd_root}/gsd)
  message(STATUS "GSD trajectories: on (gsd C library from ${_rpyfmm_gsd_root})")
elseif(NOT RPYFMM_WITH_GSD)
  set(RPYFMM_HAVE_GSD OFF)
  message(STATUS "GSD trajectories: off (RPYFMM_WITH_GSD=OFF)")
else()
  set(RPYFMM_HAVE_GSD OFF)
  message(STATUS "GSD trajectories: off (no gsd ${RPYFMM_GSD_VERSION} sources found: run "
                 "scripts/fetch-gsd.sh, or set RPYFMM_GSD_SOURCE_DIR, and configure again)")
endif()

# FindMuJoCo
# ----------
# Finds the MuJoCo C library and headers and defines the imported target MuJoCo::MuJoCo.
#
# Search order:
#   1. MUJOCO_ROOT (CMake or environment variable): a MuJoCo install or release tarball with
#      include/mujoco/mujoco.h and lib/libmujoco.so*.
#   2. MJSYSID_VENV (default: <source>/.venv): the `mujoco` / `mujoco-core` wheel installed by
#      tools/bootstrap.sh, which ships libmujoco.so.X.Y.Z and include/mujoco/ inside the package.
#
# Result variables: MuJoCo_FOUND, MuJoCo_VERSION, MuJoCo_INCLUDE_DIR, MuJoCo_LIBRARY.
# Fails (FATAL_ERROR via find_package_handle_standard_args) when the version is below the one
# requested by find_package(MuJoCo <min>).

set(_mujoco_hints)
if(MUJOCO_ROOT)
  list(APPEND _mujoco_hints "${MUJOCO_ROOT}")
elseif(DEFINED ENV{MUJOCO_ROOT})
  list(APPEND _mujoco_hints "$ENV{MUJOCO_ROOT}")
else()
  if(NOT MJSYSID_VENV)
    set(MJSYSID_VENV "${CMAKE_SOURCE_DIR}/.venv")
  endif()
  file(GLOB _mujoco_wheel_dirs "${MJSYSID_VENV}/lib/python3*/site-packages/mujoco")
  list(APPEND _mujoco_hints ${_mujoco_wheel_dirs})
endif()

find_path(MuJoCo_INCLUDE_DIR mujoco/mujoco.h
  HINTS ${_mujoco_hints} PATH_SUFFIXES include NO_DEFAULT_PATH)

# the wheel ships only the fully versioned file (libmujoco.so.X.Y.Z), so glob for it
set(MuJoCo_LIBRARY "" CACHE FILEPATH "Path to libmujoco.so")
if(NOT MuJoCo_LIBRARY)
  foreach(_dir IN LISTS _mujoco_hints)
    file(GLOB _libs "${_dir}/libmujoco.so*" "${_dir}/lib/libmujoco.so*")
    if(_libs)
      list(SORT _libs)
      list(GET _libs -1 _lib)
      set(MuJoCo_LIBRARY "${_lib}" CACHE FILEPATH "Path to libmujoco.so" FORCE)
      break()
    endif()
  endforeach()
endif()

# version from the header: X*1000000 + Y*1000 + Z since 3.4/4.x, XYZ (e.g. 330) before
if(MuJoCo_INCLUDE_DIR AND EXISTS "${MuJoCo_INCLUDE_DIR}/mujoco/mujoco.h")
  file(STRINGS "${MuJoCo_INCLUDE_DIR}/mujoco/mujoco.h" _ver_line
       REGEX "^#define[ \t]+mjVERSION_HEADER[ \t]+[0-9]+")
  string(REGEX REPLACE ".*mjVERSION_HEADER[ \t]+([0-9]+).*" "\\1" _v "${_ver_line}")
  if(_v GREATER_EQUAL 1000000)
    math(EXPR _major "${_v} / 1000000")
    math(EXPR _minor "(${_v} / 1000) % 1000")
    math(EXPR _patch "${_v} % 1000")
  else()
    math(EXPR _major "${_v} / 100")
    math(EXPR _minor "(${_v} / 10) % 10")
    math(EXPR _patch "${_v} % 10")
  endif()
  set(MuJoCo_VERSION "${_major}.${_minor}.${_patch}")
endif()

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(MuJoCo
  REQUIRED_VARS MuJoCo_LIBRARY MuJoCo_INCLUDE_DIR
  VERSION_VAR MuJoCo_VERSION
  REASON_FAILURE_MESSAGE
    "Run tools/bootstrap.sh to install the pinned MuJoCo wheel into .venv, or pass -DMUJOCO_ROOT=<dir> pointing at a MuJoCo install (include/mujoco/mujoco.h, lib/libmujoco.so).")

if(MuJoCo_FOUND AND NOT TARGET MuJoCo::MuJoCo)
  add_library(MuJoCo::MuJoCo SHARED IMPORTED)
  set_target_properties(MuJoCo::MuJoCo PROPERTIES
    IMPORTED_LOCATION "${MuJoCo_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${MuJoCo_INCLUDE_DIR}")
  get_filename_component(MuJoCo_LIBRARY_DIR "${MuJoCo_LIBRARY}" DIRECTORY)
  message(STATUS "MuJoCo ${MuJoCo_VERSION}: ${MuJoCo_LIBRARY}")
endif()
mark_as_advanced(MuJoCo_INCLUDE_DIR MuJoCo_LIBRARY)

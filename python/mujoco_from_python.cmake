# For the Python extension (MJSYSID_PYTHON): compile the libraries position-independent and take
# MuJoCo from the `mujoco` package of the Python that builds the module (pip's build environment:
# the same pinned wheel as at run time), so that `import mujoco; import mjsysid` share one
# libmujoco. An explicit MUJOCO_ROOT still wins.
set(CMAKE_POSITION_INDEPENDENT_CODE ON)
find_package(Python 3.8 REQUIRED COMPONENTS Interpreter Development.Module)
if(NOT MUJOCO_ROOT AND NOT DEFINED ENV{MUJOCO_ROOT})
  execute_process(
    COMMAND "${Python_EXECUTABLE}" -c
      "import mujoco, os; print(os.path.dirname(mujoco.__file__), end='')"
    OUTPUT_VARIABLE _mjsysid_py_mujoco RESULT_VARIABLE _mjsysid_py_rc ERROR_VARIABLE _err)
  if(NOT _mjsysid_py_rc EQUAL 0)
    message(FATAL_ERROR "MJSYSID_PYTHON: ${Python_EXECUTABLE} cannot import mujoco (pip installs "
      "the pinned wheel as a build requirement of pyproject.toml): ${_err}")
  endif()
  set(MUJOCO_ROOT "${_mjsysid_py_mujoco}")
  # pip's isolated build environments live in new temporary folders: a build folder kept from an
  # earlier `pip install` must forget the MuJoCo (and nanobind) it found there
  if(NOT "${_mjsysid_py_mujoco}" STREQUAL "${MJSYSID_PYTHON_MUJOCO}")
    unset(MuJoCo_LIBRARY CACHE)
    unset(MuJoCo_INCLUDE_DIR CACHE)
    unset(nanobind_DIR CACHE)
    set(MJSYSID_PYTHON_MUJOCO "${_mjsysid_py_mujoco}" CACHE INTERNAL "mujoco package of the build")
  endif()
endif()

# Install and export rules (`cmake --install build/default --prefix PREFIX`):
#   PREFIX/bin/sysid                          the command line (RPATH to libmujoco, see below)
#   PREFIX/lib/libmjsysid*.a                  the libraries (static)
#   PREFIX/include/{core,sysid}/...           the public headers, at the paths used in the sources
#   PREFIX/include/mjsysid/version.h          the generated version header
#   PREFIX/lib/cmake/mjsysid/                 mjsysidConfig.cmake, its version file, the exported
#                                             targets and FindMuJoCo.cmake
# A consumer calls find_package(mjsysid) and links mjsysid::core (core/: MuJoCo + Eigen),
# mjsysid::sysid (the Ceres Problem, sysid/problem.h) and mjsysid::io (YAML, HDF5, CSV,
# results); mjsysid::sim and mjsysid::run are exported too. mjsysid::types, mjsysid::residual and
# mjsysid::triangle come along as their dependencies. tests/consumer/ is such a consumer, built by
# tools/run_tests.sh.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

# target name in the build tree -> exported name mjsysid::<name>
set(_mjsysid_exported
  mjsysid_core core
  mjsysid_types types
  mjsysid_residual residual
  mjsysid_triangle triangle
  mjsysid sysid
  mjsysid_io io
  mjsysid_sim sim
  mjsysid_run run)
set(_mjsysid_libraries)
while(_mjsysid_exported)
  list(POP_FRONT _mjsysid_exported _target _name)
  set_target_properties(${_target} PROPERTIES EXPORT_NAME ${_name})
  target_include_directories(${_target} INTERFACE "$<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>")
  list(APPEND _mjsysid_libraries ${_target})
endwhile()

# the installed sysid finds its shared libraries through its RPATH: libmujoco's directory (the
# wheel in .venv, outside the system library paths; CMake leaves directories inside the source
# tree out of the automatic list, so it is named here) and the other non-system link directories
get_filename_component(_mjsysid_mujoco_lib_dir "${MuJoCo_LIBRARY}" DIRECTORY)
set_target_properties(sysid PROPERTIES INSTALL_RPATH "${_mjsysid_mujoco_lib_dir}"
  INSTALL_RPATH_USE_LINK_PATH TRUE)
install(TARGETS sysid RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(TARGETS ${_mjsysid_libraries} EXPORT mjsysidTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})

# headers: every header of core/ and sysid/ but the internal ones of the Ceres problem (the fit
# pass's stages in sysid/fit/, the fit state sysid/solve/fit_state.h and the headers that include
# it) and of the HDF5 files (hdf5.h, a private dependency)
foreach(_dir core sysid)
  install(DIRECTORY "${PROJECT_SOURCE_DIR}/${_dir}/"
    DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/${_dir}"
    FILES_MATCHING PATTERN "*.h"
    PATTERN "fit" EXCLUDE
    PATTERN "fit_state.h" EXCLUDE
    PATTERN "cost_functions.h" EXCLUDE
    PATTERN "multiple_shooting.h" EXCLUDE
    PATTERN "event_windows.h" EXCLUDE
    PATTERN "distributed_fit.h" EXCLUDE
    PATTERN "state_projection.h" EXCLUDE
    PATTERN "state_residuals.h" EXCLUDE
    PATTERN "hdf5_util.h" EXCLUDE
    PATTERN "result_internal.h" EXCLUDE)
endforeach()
install(FILES "${PROJECT_BINARY_DIR}/generated/mjsysid/version.h"
  DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}/mjsysid")

# the package: targets, config (finds the dependencies), version, FindMuJoCo
set(_mjsysid_cmake_dir "${CMAKE_INSTALL_LIBDIR}/cmake/mjsysid")
install(EXPORT mjsysidTargets NAMESPACE mjsysid:: DESTINATION "${_mjsysid_cmake_dir}")
# the MuJoCo this build compiled against: the static libraries hold its struct layouts, so the
# config asks for exactly this version, by default from this directory
get_filename_component(MJSYSID_MUJOCO_ROOT "${MuJoCo_INCLUDE_DIR}" DIRECTORY)
configure_package_config_file(cmake/mjsysidConfig.cmake.in
  "${PROJECT_BINARY_DIR}/mjsysidConfig.cmake" INSTALL_DESTINATION "${_mjsysid_cmake_dir}")
# 0.x: a minor version may break the API
write_basic_package_version_file("${PROJECT_BINARY_DIR}/mjsysidConfigVersion.cmake"
  COMPATIBILITY SameMinorVersion)
install(FILES "${PROJECT_BINARY_DIR}/mjsysidConfig.cmake"
  "${PROJECT_BINARY_DIR}/mjsysidConfigVersion.cmake" "${PROJECT_SOURCE_DIR}/cmake/FindMuJoCo.cmake"
  DESTINATION "${_mjsysid_cmake_dir}")

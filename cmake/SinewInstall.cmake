# `cmake --install` puts the libraries a lab links against, their public headers and an exported
# CMake package in a prefix: find_package(Sinew) then gives Sinew::common (geometry, FEM,
# materials, beam), Sinew::rt (the real-time tracker, which allocates nothing per frame),
# Sinew::rt_whisker_detection and Sinew::rt_stabilisation (set-up work on OpenCV), Sinew::offline
# (the plastic-strain registration: register_case and its parts, on Ipopt, NLopt, CHOLMOD and,
# inside, CGAL). Headers go to
# <prefix>/include/sinew and are included as in this tree ("rt/tracker.hpp"); detail/ headers stay
# private. tests/install builds a small outside project against the installed package.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(SINEW_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/Sinew)
set(sinew_install_targets sinew_common)
if(SINEW_BUILD_RT)
  list(APPEND sinew_install_targets sinew_rt sinew_rt_stabilisation sinew_rt_whisker_detection)
endif()
if(SINEW_BUILD_OFFLINE)
  list(APPEND sinew_install_targets sinew_offline sinew_offline_cgal sinew_cholmod)
endif()
install(TARGETS ${sinew_install_targets} EXPORT SinewTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/sinew)

set(sinew_header_dirs common)
if(SINEW_BUILD_RT)
  list(APPEND sinew_header_dirs rt)
endif()
if(SINEW_BUILD_OFFLINE)
  list(APPEND sinew_header_dirs offline)
endif()
foreach(dir ${sinew_header_dirs})
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${dir} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/sinew
          FILES_MATCHING PATTERN "*.hpp" PATTERN "detail" EXCLUDE PATTERN "experiments" EXCLUDE)
endforeach()

install(EXPORT SinewTargets NAMESPACE Sinew:: DESTINATION ${SINEW_INSTALL_CMAKEDIR})
set(SINEW_CONFIG_WITH_RT ${SINEW_BUILD_RT})
set(SINEW_CONFIG_WITH_OFFLINE ${SINEW_BUILD_OFFLINE})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/SinewConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/SinewConfig.cmake
                              INSTALL_DESTINATION ${SINEW_INSTALL_CMAKEDIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/SinewConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/SinewConfig.cmake ${PROJECT_BINARY_DIR}/SinewConfigVersion.cmake
        DESTINATION ${SINEW_INSTALL_CMAKEDIR})

# `cmake --install` of the engine as a CMake package: the public headers (include/m3c2/), the
# library and the exported target m3c2::m3c2 with its package config and version file, so that
# another C++ project uses it with find_package(m3c2 REQUIRED) (tests/consumer/).

include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(M3C2_INSTALL_CMAKEDIR "${CMAKE_INSTALL_LIBDIR}/cmake/m3c2" CACHE STRING "Where m3c2Config.cmake is installed")

install(TARGETS m3c2_core EXPORT m3c2Targets
        ARCHIVE DESTINATION "${CMAKE_INSTALL_LIBDIR}"
        LIBRARY DESTINATION "${CMAKE_INSTALL_LIBDIR}"
        RUNTIME DESTINATION "${CMAKE_INSTALL_BINDIR}"
        INCLUDES DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}")
install(DIRECTORY "${PROJECT_SOURCE_DIR}/include/m3c2" DESTINATION "${CMAKE_INSTALL_INCLUDEDIR}")
install(EXPORT m3c2Targets NAMESPACE m3c2:: DESTINATION "${M3C2_INSTALL_CMAKEDIR}")

configure_package_config_file("${CMAKE_CURRENT_LIST_DIR}/m3c2Config.cmake.in"
                              "${PROJECT_BINARY_DIR}/m3c2Config.cmake"
                              INSTALL_DESTINATION "${M3C2_INSTALL_CMAKEDIR}")
# 0.x: a minor version may change the API.
write_basic_package_version_file("${PROJECT_BINARY_DIR}/m3c2ConfigVersion.cmake" COMPATIBILITY SameMinorVersion)
install(FILES "${PROJECT_BINARY_DIR}/m3c2Config.cmake" "${PROJECT_BINARY_DIR}/m3c2ConfigVersion.cmake"
        DESTINATION "${M3C2_INSTALL_CMAKEDIR}")

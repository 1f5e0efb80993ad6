# `cmake --install build --prefix P`: the libraries, their public headers (P/include/displace,
# included as "pipeline/frame_pipeline.h") and a CMake package, so that another project's
#   find_package(displace 0.1 CONFIG REQUIRED)
#   target_link_libraries(app PRIVATE displace::pipeline)
# gets displace::sim, displace::bake, displace::vulkan, displace::sim_device, displace::bake_device,
# displace::render and displace::pipeline with their dependencies found (cmake/displaceConfig.cmake.in).
# Version: the project's (displace_VERSION); versions with the same major and minor number are
# compatible (README, "Using the libraries").
include(CMakePackageConfigHelpers)
include(GNUInstallDirs)

set(DISPLACE_CMAKE_INSTALL_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/displace)
set_target_properties(displace_sim PROPERTIES EXPORT_NAME sim)
set_target_properties(displace_bake PROPERTIES EXPORT_NAME bake)
set_target_properties(displace_vulkan PROPERTIES EXPORT_NAME vulkan)
set_target_properties(displace_sim_device PROPERTIES EXPORT_NAME sim_device)
set_target_properties(displace_bake_device PROPERTIES EXPORT_NAME bake_device)
set_target_properties(displace_render PROPERTIES EXPORT_NAME render)
set_target_properties(displace_pipeline PROPERTIES EXPORT_NAME pipeline)
install(TARGETS displace_sim displace_bake displace_vulkan displace_sim_device displace_bake_device displace_render
                displace_pipeline
        EXPORT displaceTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        FILE_SET HEADERS DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/displace)
install(EXPORT displaceTargets NAMESPACE displace:: DESTINATION ${DISPLACE_CMAKE_INSTALL_DIR})
configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/displaceConfig.cmake.in
                              ${CMAKE_CURRENT_BINARY_DIR}/displaceConfig.cmake
                              INSTALL_DESTINATION ${DISPLACE_CMAKE_INSTALL_DIR})
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/displaceConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/displaceConfig.cmake ${CMAKE_CURRENT_BINARY_DIR}/displaceConfigVersion.cmake
        DESTINATION ${DISPLACE_CMAKE_INSTALL_DIR})

# the same names in this build tree, for code that is built with the project
add_library(displace::sim ALIAS displace_sim)
add_library(displace::bake ALIAS displace_bake)
add_library(displace::vulkan ALIAS displace_vulkan)
add_library(displace::sim_device ALIAS displace_sim_device)
add_library(displace::bake_device ALIAS displace_bake_device)
add_library(displace::render ALIAS displace_render)
add_library(displace::pipeline ALIAS displace_pipeline)

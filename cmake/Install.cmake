# cmake --install: libpenumbra, the rendering core, and libpenumbra_app, pictures and
# optimisers (shared, with SOVERSION; static with -DBUILD_SHARED_LIBS=OFF), the public headers
# (include/penumbra/), the CMake package (lib/cmake/penumbra: targets penumbra::penumbra and
# penumbra::app), pkg-config's penumbra.pc and penumbra-app.pc, the tool and the bundled data
# (share/penumbra: scenes, meshes, targets). The kernels and the shipped tuning defaults are
# compiled into the library, so an installed copy needs nothing from the source tree.
include(CMakePackageConfigHelpers)
set(PENUMBRA_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/penumbra)

install(TARGETS penumbra_core penumbra_app EXPORT penumbraTargets COMPONENT dev
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} NAMELINK_COMPONENT dev
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(DIRECTORY ${CMAKE_SOURCE_DIR}/host/include/penumbra
                  ${CMAKE_BINARY_DIR}/generated/include/penumbra
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT dev)
install(EXPORT penumbraTargets NAMESPACE penumbra:: DESTINATION ${PENUMBRA_CMAKE_DIR}
        COMPONENT dev)
configure_package_config_file(${CMAKE_SOURCE_DIR}/cmake/penumbraConfig.cmake.in
  ${CMAKE_BINARY_DIR}/penumbraConfig.cmake INSTALL_DESTINATION ${PENUMBRA_CMAKE_DIR}
  PATH_VARS CMAKE_INSTALL_DATADIR)
# Before 1.0 every minor version may change the API.
write_basic_package_version_file(${CMAKE_BINARY_DIR}/penumbraConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/penumbraConfig.cmake ${CMAKE_BINARY_DIR}/penumbraConfigVersion.cmake
        DESTINATION ${PENUMBRA_CMAKE_DIR} COMPONENT dev)

# pkg-config: relocatable (paths relative to the .pc file); a static library also needs its
# private dependencies.
file(RELATIVE_PATH PENUMBRA_PC_TO_PREFIX ${CMAKE_INSTALL_FULL_LIBDIR}/pkgconfig
     ${CMAKE_INSTALL_PREFIX})
set(PENUMBRA_PC_REQUIRES_PRIVATE "")
set(PENUMBRA_APP_PC_REQUIRES_PRIVATE "")
set(PENUMBRA_APP_PC_LIBS_PRIVATE "")
if(NOT BUILD_SHARED_LIBS)
  set(PENUMBRA_PC_REQUIRES_PRIVATE "clblast tinyobjloader_double assimp")
  set(PENUMBRA_APP_PC_REQUIRES_PRIVATE "stb")
  set(PENUMBRA_APP_PC_LIBS_PRIVATE "-lgif")  # giflib has no .pc file
endif()
configure_file(${CMAKE_SOURCE_DIR}/cmake/penumbra.pc.in ${CMAKE_BINARY_DIR}/penumbra.pc @ONLY)
configure_file(${CMAKE_SOURCE_DIR}/cmake/penumbra-app.pc.in ${CMAKE_BINARY_DIR}/penumbra-app.pc @ONLY)
install(FILES ${CMAKE_BINARY_DIR}/penumbra.pc ${CMAKE_BINARY_DIR}/penumbra-app.pc
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig COMPONENT dev)

if(PENUMBRA_BUILD_CLI)
  install(TARGETS penumbra RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT cli)
  if(PENUMBRA_WARM_KERNEL_CACHE)  # loads what the build filled: a second or so
    install(CODE "execute_process(COMMAND \${CMAKE_COMMAND}
                  -DCLI=\$ENV{DESTDIR}\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_BINDIR}/penumbra
                  -P ${CMAKE_SOURCE_DIR}/cmake/WarmKernelCache.cmake)" COMPONENT cli)
  endif()
endif()
install(DIRECTORY ${CMAKE_SOURCE_DIR}/data/scenes ${CMAKE_SOURCE_DIR}/data/meshes
                  ${CMAKE_SOURCE_DIR}/data/targets
        DESTINATION ${CMAKE_INSTALL_DATADIR}/penumbra COMPONENT data
        PATTERN "*.py" EXCLUDE)

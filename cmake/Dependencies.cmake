# Every dependency comes from a Debian package; a missing one stops configuration with the
# name of the package to install.
find_package(PkgConfig QUIET)

macro(penumbra_require found package)
  if(NOT ${found})
    message(FATAL_ERROR "penumbra: missing dependency; install the Debian package '${package}' "
                        "(apt-get install ${package}), or run ./scripts/setup.sh")
  endif()
endmacro()

find_package(OpenCL QUIET)
penumbra_require(OpenCL_FOUND "ocl-icd-opencl-dev opencl-headers")
find_package(OpenCLHeaders QUIET)  # OpenCLHeadersCpp needs it found first
find_package(OpenCLHeadersCpp QUIET)
penumbra_require(OpenCLHeadersCpp_FOUND "opencl-clhpp-headers")
find_package(CLBlast QUIET)
penumbra_require(CLBlast_FOUND "libclblast-dev")
find_package(glm QUIET)
penumbra_require(glm_FOUND "libglm-dev")
find_package(nlohmann_json QUIET)
penumbra_require(nlohmann_json_FOUND "nlohmann-json3-dev")
find_package(tinyobjloader QUIET)
penumbra_require(tinyobjloader_FOUND "libtinyobjloader-dev")
find_package(assimp QUIET)  # the mesh formats other than OBJ
penumbra_require(assimp_FOUND "libassimp-dev")
if(PENUMBRA_BUILD_CLI)
  find_package(CLI11 QUIET)
  penumbra_require(CLI11_FOUND "libcli11-dev")
endif()
penumbra_require(PKG_CONFIG_FOUND "pkg-config")
pkg_check_modules(STB QUIET IMPORTED_TARGET stb)
penumbra_require(STB_FOUND "libstb-dev")
find_package(GIF QUIET)  # giflib: the animation writer
penumbra_require(GIF_FOUND "libgif-dev")
if(PENUMBRA_BUILD_TESTS)
  find_package(GTest QUIET)
  penumbra_require(GTest_FOUND "libgtest-dev")
endif()
if(PENUMBRA_BUILD_BENCH)
  find_package(benchmark QUIET)
  penumbra_require(benchmark_FOUND "libbenchmark-dev")
endif()

# Compiler warnings of penumbra's own targets (README, "Code style and lint").
#
# penumbra_warnings(target) gives `target` -Wall -Wextra and, with PENUMBRA_WERROR=ON (the
# default), -Werror: a warning fails the build. Every target of the build calls it — library,
# tool, tests, benchmarks, fuzzers, Python module — and nothing else sets warning flags.
# Configure with -DPENUMBRA_WERROR=OFF to build with a compiler that warns where GCC 12 and
# clang 15 do not.
# Under the sanitizers (PENUMBRA_SANITIZE) GCC's -Wmaybe-uninitialized is left out: with GCC 12
# and ASan it reports std::function members inside libstdc++'s <regex> (every report of a
# whole sanitizer build, none in penumbra's code), which the instrumentation confuses.
option(PENUMBRA_WERROR "Treat compiler warnings as errors (-Werror) on every penumbra target" ON)

function(penumbra_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra $<$<BOOL:${PENUMBRA_WERROR}>:-Werror>)
  if(PENUMBRA_SANITIZE AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    target_compile_options(${target} PRIVATE -Wno-maybe-uninitialized)
  endif()
endfunction()

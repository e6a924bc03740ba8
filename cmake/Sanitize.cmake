# Sanitizer and fuzzing builds (see README, "Hardening").
#
# PENUMBRA_SANITIZE=address,undefined (any list that -fsanitize= takes) instruments every target
# of the build — host library, tool, tests, benchmarks — with GCC or clang. The preset `asan`
# selects it; `scripts/test.sh asan` builds and runs the test suite that way. The runtime options
# that PoCL needs inside an instrumented process are compiled into every executable of the
# build (cmake/sanitizer_defaults.cpp); the environment variables ASAN_OPTIONS, UBSAN_OPTIONS
# and LSAN_OPTIONS still override them.
#
# PENUMBRA_FUZZ=ON builds the libFuzzer targets of tests/fuzz with clang:
# -fsanitize=fuzzer-no-link,address,undefined on every object, -fsanitize=fuzzer on the fuzzer
# executables. The preset `fuzz` selects it; scripts/fuzz.sh builds and runs them.

if(PENUMBRA_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(FATAL_ERROR "penumbra: PENUMBRA_FUZZ needs clang (libFuzzer), not "
                        "${CMAKE_CXX_COMPILER_ID}; configure with -DCMAKE_CXX_COMPILER=clang++-15 "
                        "(Debian: apt-get install clang-15, which PoCL already depends on)")
  endif()
  if(PENUMBRA_SANITIZE AND NOT PENUMBRA_SANITIZE STREQUAL "address,undefined")
    message(FATAL_ERROR "penumbra: PENUMBRA_FUZZ uses address,undefined; leave PENUMBRA_SANITIZE "
                        "empty (it is '${PENUMBRA_SANITIZE}')")
  endif()
  set(PENUMBRA_SANITIZE "address,undefined")
  add_compile_options(-fsanitize=fuzzer-no-link)
endif()

if(PENUMBRA_SANITIZE)
  message(STATUS "penumbra: sanitizers ${PENUMBRA_SANITIZE} on every target")
  # UBSan's findings are errors: no recovery, so that a finding fails the test that hit it
  # whatever UBSAN_OPTIONS says.
  add_compile_options(-fsanitize=${PENUMBRA_SANITIZE} -fno-sanitize-recover=all
                      -fno-omit-frame-pointer -g)
  add_link_options(-fsanitize=${PENUMBRA_SANITIZE})
endif()

# Adds the default sanitizer runtime options to every executable that links `target`.
function(penumbra_sanitizer_defaults target)
  if(PENUMBRA_SANITIZE)
    target_sources(${target} INTERFACE $<BUILD_INTERFACE:${CMAKE_SOURCE_DIR}/cmake/sanitizer_defaults.cpp>)
  endif()
endfunction()

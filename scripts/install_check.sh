#!/usr/bin/env bash
# Installs a built penumbra into a temporary prefix and uses it the way another project would,
# from outside the source tree:
#   1. cmake --install of build/ (or $PENUMBRA_BUILD_DIR) into a scratch prefix;
#   2. examples/cpp, copied out of the tree, configured with find_package(penumbra) against that
#      prefix, built and run: it renders the installed bundled scene and runs one backward;
#   3. the same source built with pkg-config's flags for penumbra.pc, and run;
#   4. the installed tool renders the installed bundled scene.
# Fails if the library or the headers mention the source tree, or if any step fails.
# Usage: scripts/install_check.sh   (after scripts/build.sh; PENUMBRA_BUILD_DIR=build-static for a
#        build configured with -DBUILD_SHARED_LIBS=OFF)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
src=$(pwd)
build=${PENUMBRA_BUILD_DIR:-build}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
prefix=$tmp/prefix
# Compiled kernels go to the scratch folder, not to the user's kernel cache (README).
export PENUMBRA_CACHE_DIR=${PENUMBRA_CACHE_DIR:-$tmp/kernel_cache}

cmake --install "$build" --prefix "$prefix" >"$tmp/install.log"
echo "install_check: installed $(wc -l <"$build/install_manifest.txt") files into a scratch prefix"
if grep -rlF "$src" "$prefix/lib" "$prefix/include" "$prefix/share"; then
  echo "install_check: the installed files above name the source tree $src" >&2
  exit 1
fi

# Warnings are errors here as in penumbra's own build (README, "Code style and lint").
warnings="-Wall -Wextra -Werror"
cp -r examples/cpp "$tmp/example"
cmake -S "$tmp/example" -B "$tmp/example-build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_CXX_FLAGS="$warnings" >"$tmp/configure.log"
cmake --build "$tmp/example-build" >"$tmp/build.log"
(cd "$tmp" && ./example-build/render_and_backward)
test -s "$tmp/render.png"

pcdir=$(dirname "$(find "$prefix" -name penumbra.pc)")
static=()  # a static libpenumbra needs its private dependencies: pkg-config --static
[[ -n "$(find "$prefix" -name 'libpenumbra.so*')" ]] || static=(--static)
# shellcheck disable=SC2046,SC2086  # pkg-config's flags and $warnings: one word per flag
g++ -std=c++17 -O1 $warnings -o "$tmp/example-pc" examples/cpp/render_and_backward.cpp \
  -DSCENE="\"$(PKG_CONFIG_PATH="$pcdir" pkg-config --variable=datadir penumbra)/scenes/turnaround.json\"" \
  $(PKG_CONFIG_PATH="$pcdir" pkg-config "${static[@]}" --cflags --libs penumbra-app) \
  -Wl,-rpath,"$(dirname "$pcdir")"
(cd "$tmp" && ./example-pc >/dev/null)

(cd "$tmp" && "$prefix/bin/penumbra" render -o "$tmp/cli.png" --width 64 --height 64)
echo "install_check: passed (find_package, pkg-config and the installed tool)"

#!/usr/bin/env bash
# Configures and builds Moreau (Release, Ninja) into build/. Extra arguments go to CMake's configure,
# e.g. scripts/build.sh -DMOREAU_SANITIZE=ON. BUILD_DIR overrides the build directory.
#
# When ccache is installed, compilations go through it, with paths taken relative to the checkout
# (CCACHE_BASEDIR), so a second build of the same sources, even from another clone of the repository
# on the same machine (as CI does), reuses the objects instead of compiling them again.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
launcher=()
if command -v ccache >/dev/null 2>&1; then
  export CCACHE_BASEDIR=$PWD
  # Identical sources in two clones differ only in their absolute paths; with no debug information in a
  # Release build, the paths do not reach the objects, so the cache may ignore them.
  export CCACHE_NOHASHDIR=1
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
start=$(date +%s)
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" "$@"
cmake --build "$build_dir" -j "$(nproc)"
echo "build: $build_dir built in $(( $(date +%s) - start )) s${launcher:+ (through ccache)}"

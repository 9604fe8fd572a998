#!/usr/bin/env bash
# Configures and builds Moreau (Release, Ninja) into build/. Extra arguments go to CMake's configure,
# e.g. scripts/build.sh -DMOREAU_SANITIZE=ON. BUILD_DIR overrides the build directory.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${BUILD_DIR:-build}
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "$@"
cmake --build "$build_dir" -j "$(nproc)"

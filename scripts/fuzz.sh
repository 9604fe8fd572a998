#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (ASan + UBSan + coverage) into build-fuzz/ and runs each for
# SECONDS (default 60) from a copy of its checked-in seed corpus. Prints executions and whether a crash
# was found; a crash leaves its input as build-fuzz/crash-* and fails the script.
# TARGETS (default: all five) picks some: TARGETS="urdf campaign" scripts/fuzz.sh 600
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMOREAU_FUZZ=ON \
  -DMOREAU_BUILD_TESTS=OFF -DMOREAU_BUILD_BENCH=OFF >/dev/null
targets=${TARGETS:-expression scene http urdf campaign}
cmake --build build-fuzz -j "$(nproc)" --target $(for t in $targets; do printf '%s_fuzzer ' "$t"; done)
status=0
for target in $targets; do
  work=build-fuzz/corpus-$target
  mkdir -p "$work"
  cp -n fuzz/corpus/$target/* "$work"/ 2>/dev/null || true
  echo "== ${target}_fuzzer for ${seconds} s"
  if ! ./build-fuzz/fuzz/${target}_fuzzer "$work" -max_total_time="$seconds" -max_len=4096 -timeout=10 \
      -rss_limit_mb=2048 -artifact_prefix=build-fuzz/ -print_final_stats=1 2>&1 | tee build-fuzz/$target.log |
      grep -E "^(#[0-9]+ +DONE|stat::number_of_executed_units|==[0-9]+==ERROR|SUMMARY)"; then
    :
  fi
  grep -q "ERROR\|deadly signal\|Timeout" build-fuzz/$target.log && status=1
done
exit $status

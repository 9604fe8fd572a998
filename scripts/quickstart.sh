#!/usr/bin/env bash
# From a fresh Debian 12 machine to the paper's manipulator: installs the build dependencies, builds,
# and runs scenes/manipulator.json (section 6 of Adly, Brogliato and Le 2016), printing its report and
# writing its trajectory (and figures, when the build has render/) under out/.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$(date +%s)
bash scripts/install-deps.sh
bash scripts/build.sh
mkdir -p out
args=(run scenes/manipulator.json --out out/manipulator.csv)
if ./build/client/moreau run --help 2>/dev/null | grep -q -- '--figure'; then
  args+=(--figure out/manipulator-state.png --figure energy=out/manipulator-energy.png)
fi
./build/client/moreau "${args[@]}"
echo "trajectory: out/manipulator.csv$(ls out/*.png >/dev/null 2>&1 && echo '; figures:' out/*.png)"
echo "built: build/client/moreau (the command line), build/server/moreau-server (the HTTP service); $(( $(date +%s) - start )) s in all"
echo "next: ctest --test-dir build --output-on-failure -j2 (the tests); README.md, 'Using it'"

#!/usr/bin/env bash
# Installs Moreau's build dependencies from Debian 12 packages. Idempotent: packages already present
# are left alone, and apt is not even called when nothing is missing.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev                      # core numerics
  nlohmann-json3-dev libcli11-dev    # scene format, command line
  liblcm-dev liblcm-bin libglib2.0-dev  # live state (lcm.pc needs glib-2.0 and gthread-2.0)
  libosmesa6-dev libfreetype-dev libpng-dev fonts-dejavu-core  # figures
  libcpp-httplib-dev                 # server
  libboost-dev                       # Boost.Odeint (rosenbrock4), the stiff peer of studies
  libgtest-dev libgmock-dev libbenchmark-dev  # tests, benchmarks
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
sudo_cmd=()
[ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
"${sudo_cmd[@]}" apt-get update -qq
DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"

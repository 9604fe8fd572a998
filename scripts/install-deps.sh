#!/usr/bin/env bash
# Installs Moreau's build dependencies from Debian 12 packages. Idempotent: packages already present
# are left alone, and apt is not even called when nothing is missing. Installing needs root or sudo;
# without either, the script names the missing packages and the apt-get command to run as root.
#
# Options (CI passes all three; a user needs none):
#   --browser-test  what the web page's browser test needs: Debian's chromium, and puppeteer-core from the
#                   npm registry into tests/server/browser/node_modules (npm ci, from the lock file), with the
#                   machine's Node.js. Without it that test is not registered (CMake says so).
#   --format-check  clang-format (Debian's, version 14), which CI runs over every C++ file: the tree is
#                   formatted by .clang-format, and a difference fails CI.
#   --slurm-test    slurmctld, slurmd, slurm-client and munge, for the test that runs a campaign through a
#                   real single-node Slurm cluster (tests/client/slurm/). On a machine with systemd, Debian enables
#                   and starts those daemons when it installs them, so they are not installed by default;
#                   without them that test is skipped (exit 77), unless MOREAU_REQUIRE_SLURM=1.
# apt's output goes to a log, shown only if apt fails.
set -euo pipefail
cd "$(dirname "$0")/.."

browser_test=false
slurm_test=false
format_check=false
for arg in "$@"; do
  case $arg in
    --browser-test) browser_test=true ;;
    --slurm-test) slurm_test=true ;;
    --format-check) format_check=true ;;
    *) echo "install-deps: unknown argument $arg (the options are --browser-test, --slurm-test and --format-check)" >&2; exit 2 ;;
  esac
done

packages=(
  build-essential cmake ninja-build pkg-config
  ccache                             # scripts/build.sh compiles through it: a rebuild of unchanged sources takes seconds
  libeigen3-dev                      # core numerics
  libxbyak-dev                       # native code for the expression tapes (x86-64)
  nlohmann-json3-dev libcli11-dev    # scene format, command line
  liblcm-dev liblcm-bin libglib2.0-dev  # live state (lcm.pc needs glib-2.0 and gthread-2.0)
  libosmesa6-dev libfreetype-dev libpng-dev fonts-dejavu-core  # figures
  libcpp-httplib-dev zlib1g-dev      # server (zlib: the hostile-client test makes gzip bodies)
  libjs-three                        # three.js (MIT), compiled into the server for the page's 3D view of a robot
  libboost-dev                       # Boost.Odeint (rosenbrock4), the stiff peer of studies; Boost.Random's Sobol
                                     # sequence and Boost.Math's normal quantile for campaigns
  liburdfdom-dev                     # robots from URDF (the URDF module)
  libexpat1-dev                      # the URDF module: nesting and size checked by a non-recursive XML parser first
  liborocos-kdl-dev                  # tests: KDL, the independent reference for the rigid-body algorithms
  libgtest-dev libgmock-dev libbenchmark-dev  # tests, benchmarks
  iproute2                           # `ip`, for tests/server/lcm_udpm_netns.sh (multicast in a private netns)
  python3                            # scripts/check-scene-results.py (shipped scenes against references)
  python3-jsonschema                 # tests/server/check_openapi.py (server/openapi.json against the OpenAPI 3.1 schema)
  python3-numpy                      # tests/client/python_client_test.py (the Python client returns numpy arrays when it can)
  python3-yaml                       # tests/client/k8s_indexed_job_test.py (reads the Kubernetes manifest)
  python3-dev pybind11-dev           # the Python module `moreau` (python/, docs/python.md)
  python3-pil                        # tests/render/reference_figures_test.py (figures against their reference images)
  python3-pytest python3-pandas      # the package's tests (tests/python/, tests/client/python_client_test.py);
                                     # pandas for Result.to_pandas()
)
if $browser_test; then packages+=(chromium); fi
if $slurm_test; then packages+=(slurmctld slurmd slurm-client munge); fi
if $format_check; then packages+=(clang-format); fi  # tests/client/slurm/: a real single-node cluster

# puppeteer-core for the browser test, once the packages are there (it drives /usr/bin/chromium).
install_browser_driver() {
  $browser_test || return 0
  if [ -f tests/server/browser/node_modules/puppeteer-core/package.json ]; then
    echo "install-deps: puppeteer-core present in tests/server/browser"
    return 0
  fi
  if ! command -v npm >/dev/null 2>&1; then
    echo "install-deps: --browser-test needs npm (Node.js 18 or later) to install puppeteer-core" >&2
    exit 1
  fi
  echo "install-deps: npm ci in tests/server/browser (puppeteer-core)"
  (cd tests/server/browser && npm ci --no-fund --no-audit --loglevel=error)
}

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  install_browser_driver
  exit 0
fi

# What to run by hand when this script cannot install: the same commands, as root.
print_root_command() {
  echo "install-deps: to install them by hand, run as root (then run $0 again):" >&2
  echo "  apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends ${missing[*]}" >&2
}

sudo_cmd=()
if [ "$(id -u)" -ne 0 ]; then
  if ! command -v sudo >/dev/null 2>&1; then
    echo "install-deps: missing Debian packages: ${missing[*]}" >&2
    echo "install-deps: installing them needs root, and this user ($(id -un)) is not root and has no sudo." >&2
    print_root_command
    exit 1
  fi
  sudo_cmd=(sudo)
fi

echo "install-deps: installing ${#missing[@]} packages: ${missing[*]}"
apt_log=$(mktemp)
if ! "${sudo_cmd[@]}" apt-get update -qq >"$apt_log" 2>&1 ||
   ! "${sudo_cmd[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >>"$apt_log" 2>&1; then
  cat "$apt_log" >&2
  rm -f "$apt_log"
  echo "install-deps: apt-get failed (its output is above); the packages still missing are among: ${missing[*]}" >&2
  print_root_command
  exit 1
fi
rm -f "$apt_log"
echo "install-deps: installed ${#missing[@]} packages"
install_browser_driver

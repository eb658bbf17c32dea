#!/usr/bin/env bash
# Installs the Debian packages the project builds against, then configures and builds it.
# Idempotent: packages already present are left alone, and the build is incremental.
set -euo pipefail

packages=(
  build-essential cmake ccache pkg-config
  libtorch-dev libgloo-dev libopenblas0-pthread libblas-dev
  libopencv-dev libjpeg-dev libeigen3-dev nlohmann-json3-dev libcli11-dev
  libgtest-dev libgmock-dev libbenchmark-dev
)
# Without these the build still succeeds and leaves out what needs them (CMake says which).
optional_packages=(
  libcpp-httplib-dev  # the HTTP server, ffloc serve
  pybind11-dev python3-dev python3-numpy python3-pytest  # the Python module (docs/python.md) and its tests
  chromium  # the browser tests of the eval report and the server's viewer (web/)
  python3-torch  # the PyTorch eager comparator of make bench and its fixture test (bench/dust3r_eager.py)
)

not_installed() {
  local p
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || echo "$p"
  done
}
mapfile -t missing < <(not_installed "${packages[@]}")
mapfile -t missing_optional < <(not_installed "${optional_packages[@]}")

sudo_cmd=()
[ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
if ((${#missing[@]} + ${#missing_optional[@]})); then
  "${sudo_cmd[@]}" apt-get update -qq || echo "setup: apt-get update failed; trying the install anyway"
fi
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
if ((${#missing_optional[@]})); then
  echo "setup: installing ${missing_optional[*]} (optional)"
  DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing_optional[@]}" ||
    echo "setup: could not install ${missing_optional[*]}; building without what needs them"
fi
if ! ((${#missing[@]} + ${#missing_optional[@]})); then
  echo "setup: all Debian packages present"
fi

# Reference BLAS makes fp32 matmul ~40x slower than OpenBLAS; make sure OpenBLAS backs libblas.
blas=$(update-alternatives --query libblas.so.3-x86_64-linux-gnu 2>/dev/null | awk '/^Value:/{print $2}')
if [ -n "$blas" ] && ! echo "$blas" | grep -q openblas; then
  candidate=$(update-alternatives --list libblas.so.3-x86_64-linux-gnu | grep openblas-pthread | head -n1)
  if [ -n "$candidate" ]; then
    sudo_cmd=()
    [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
    "${sudo_cmd[@]}" update-alternatives --set libblas.so.3-x86_64-linux-gnu "$candidate"
  fi
fi

build_dir=${BUILD_DIR:-build}
cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE=Release
cmake --build "$build_dir" -j "$(nproc)"

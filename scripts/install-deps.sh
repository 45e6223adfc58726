#!/usr/bin/env bash
# Installs every build and test dependency of rpyfmm from Debian's packages, the sources of
# gsd's C library for GSD trajectories (fetch-gsd.sh: Debian packages only gsd's Python module),
# then the Python module's build/test packages from PyPI (install-python-deps.sh).
# Idempotent: packages already present are skipped quickly by apt.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  ccache  # compiler cache used by .ci/run (its builds share most objects)
  curl ca-certificates  # fetch-gsd.sh downloads gsd's source distribution
  libeigen3-dev libfftw3-dev libboost-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev libtomlplusplus-dev librandom123-dev libfmt-dev
  libopenmpi-dev openmpi-bin libfftw3-mpi-dev  # the optional MPI layer (RPYFMM_USE_MPI, docs/mpi.md), its tests
  python3 python3-dev python3-pip python3-venv
  python3-mpi4py  # rpyfmm.mpi, the MPI layer from Python (docs/mpi.md, "Python (mpi4py)"), and its tests
  doxygen  # the API reference (`docs` target, built in CI with warnings as errors)
  clang-format  # scripts/check-format.sh, run by .ci/run
  clang libclang-rt-14-dev  # libFuzzer and sanitizer runtimes for tests/fuzz/run.sh (Debian 12: clang 14)
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]})); then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y --no-install-recommends "${missing[@]}"
fi

bash "$(dirname "$0")/fetch-gsd.sh"
bash "$(dirname "$0")/install-python-deps.sh"

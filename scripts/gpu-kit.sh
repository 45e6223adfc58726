#!/usr/bin/env bash
# Prepares gpu-kit/ for a GPU check on a machine without the build dependencies (the lent
# device machine has CUDA and cuFFT but none of Debian's packages and no network): builds
# the release preset with CUDA here, then copies the PSE test and benchmark programs and the
# shared libraries they need beyond CUDA's own (FFTW, libgomp, the CUDA runtime).
# Then run scripts/gpu-check.sh there with gpu-kit carried (bench/README.md, section PSE on a GPU).
set -euo pipefail
cd "$(dirname "$0")/.."
command -v nvcc >/dev/null || export PATH=/usr/local/cuda/bin:$PATH
cmake --preset release -DRPYFMM_USE_CUDA=ON > /dev/null
cmake --build --preset release --target test_pse bench_pse bench_bd
grep -q "RPYFMM_USE_CUDA:BOOL=ON" build/release/CMakeCache.txt || { echo "gpu-kit: CUDA is off in build/release" >&2; exit 1; }
rm -rf gpu-kit && mkdir -p gpu-kit/lib
cp build/release/tests/pse/test_pse build/release/bench/pse/bench_pse build/release/bench/bd/bench_bd gpu-kit/
for lib in $(ldd gpu-kit/test_pse gpu-kit/bench_pse gpu-kit/bench_bd | awk '/libfftw3|libgomp|libcudart/ {print $3}' | sort -u); do
  cp -L "$lib" gpu-kit/lib/
done
ls -la gpu-kit gpu-kit/lib

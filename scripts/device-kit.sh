#!/usr/bin/env bash
# Prepares gpu-kit/ for a check of the whole test suite and the instruction-set benchmark rows on a
# lent machine without the build dependencies (scripts/device-suite.sh runs them there): builds
# the release preset with CUDA here, packs every test and benchmark program with ctest's files
# into gpu-kit/build.tar.xz (unpacked there into build/release), and copies the shared libraries
# they need beyond CUDA's own (FFTW, libgomp, the CUDA runtime) and the commit they were built
# from. scripts/gpu-kit.sh's programs (test_pse, bench_pse, bench_bd) come along, so that
# scripts/gpu-check.sh runs from the same kit.
set -euo pipefail
cd "$(dirname "$0")/.."
command -v nvcc >/dev/null || export PATH=/usr/local/cuda/bin:$PATH
cmake --preset release -DRPYFMM_USE_CUDA=ON >/dev/null
cmake --build --preset release -j2
grep -q "RPYFMM_USE_CUDA:BOOL=ON" build/release/CMakeCache.txt || { echo "device-kit: CUDA is off in build/release" >&2; exit 1; }
rm -rf gpu-kit && mkdir -p gpu-kit/lib
# ctest's files and the programs; not the object files, the libraries or the package tests'
# install trees (those tests configure CMake projects and need the build
# dependencies, which the lent machine does not have).
{
  find build/release -path '*/CMakeFiles' -prune -o -type f \
    \( -name CTestTestfile.cmake -o -name '*_tests.cmake' -o -name '*_include.cmake' \) -print
  find build/release -path '*/CMakeFiles' -prune -o -path build/release/tests/package -prune -o \
    -path build/release/python -prune -o -path 'build/release/_deps' -prune -o -type f -perm -u+x ! -name '*.so*' -print
  # The Python package (its extension links the project's libraries statically): the device
  # array tests (tests/python/test_device_arrays.py) run where the lent machine's Python matches.
  find build/release/python/rpyfmm -maxdepth 1 -type f
} | sort -u >gpu-kit/files.txt
# The device tests scripts/device-suite.sh runs by path.
for program in build/release/tests/pse/test_pse build/release/tests/bd/test_bd_device; do
  grep -qx "$program" gpu-kit/files.txt || { echo "device-kit: $program is not packed" >&2; exit 1; }
done
tar -cf - -T gpu-kit/files.txt | xz -T2 -6 >gpu-kit/build.tar.xz
cp build/release/tests/pse/test_pse build/release/bench/pse/bench_pse build/release/bench/bd/bench_bd gpu-kit/
for lib in $(ldd gpu-kit/test_pse gpu-kit/bench_pse gpu-kit/bench_bd build/release/apps/rpyfmm |
  awk '/libfftw3|libgomp|libcudart/ {print $3}' | sort -u); do
  cp -L "$lib" gpu-kit/lib/
done
commit=$(git rev-parse --short=12 HEAD)
if git status --porcelain --untracked-files=no | grep -q .; then commit="$commit+dirty"; fi
echo "$commit" >gpu-kit/COMMIT
du -sh gpu-kit gpu-kit/build.tar.xz

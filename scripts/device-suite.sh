#!/usr/bin/env bash
# Runs on the lent machine (16 cores; an AVX-512 CPU where it has one), in the repository root,
# with gpu-kit/ carried (scripts/device-kit.sh builds it):
#   1. the CUDA tests (test_pse PseCuda.*; RPYFMM_EXPECT_CUDA: no usable device is a failure);
#      the BD device engine's tests (test_bd_device DeviceEngine.*, DeviceRestart.*, DeviceRun.*,
#      DeviceIntegrator.*, DevicePse.*:
#      against the host launcher bit for bit, docs/gpu-bd.md), then compute-sanitizer memcheck and
#      racecheck on two short ones where compute-sanitizer is installed (errors fail the suite;
#      each tool within 60 s); the Python device-array tests (tests/python/test_device_arrays.py and
#      test_libmobility_device.py) where this machine's Python imports the carried extension;
#   2. the whole C++ suite at the CPU's own instruction-set level (ctest, slow tests included;
#      not the Python and package tests, which need the build dependencies);
#   3. the GPU benchmark groups (bd-gpu: the device BD engine at 1e6 particles per rebuild strategy
#      and the CPU engine on the host's cores; pse-gpu), within 120 s;
#   4. the instruction-set rows of bench/ (bench/run.py --simd-levels --isa-rows: Laplace FMM and
#      FmmRpy at 1e6 and 1e-6, the direct kernels at 1e4, PSE at 1e5, one thread, the native level and
#      AVX2 side by side, three rounds each, all at once on separate physical cores; each group
#      within what is left of RPYFMM_BENCH_BUDGET seconds).
# Output under $OUT (or ./gpu-out): device.txt, test_pse_cuda.txt, test_bd_device.txt, test_python_device.txt,
# sanitizer_bd_*.txt, ctest.txt, bench.txt and
# results.tar.gz (bench/results/*.simd-levels.json, bd-gpu.json, pse-gpu.json). Exit status non-zero if a test failed.
set -uo pipefail
cd "$(dirname "$0")/.."
source scripts/gpu-env.sh
# ctest's files name the programs by the absolute paths of the build machine's checkout.
[ -d /work/main ] || { mkdir -p /work && ln -sfn "$PWD" /work/main; }
xz -dc gpu-kit/build.tar.xz | tar -xf -
{
  lscpu | grep -E "Model name|^CPU\(s\)|Thread|Core|Socket"
  echo "vector extensions: $(grep -o -w -E 'avx2|fma|avx512f|avx512dq|avx512vl' /proc/cpuinfo | sort -u | tr '\n' ' ')"
  nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv 2>&1
  echo "commit: $(cat gpu-kit/COMMIT)"
  command -v ctest cmake g++ python3
  python3 -c "import sys, sysconfig; print(sys.version.split()[0], sysconfig.get_paths()['include'])"
  ls "$(python3 -c "import sysconfig; print(sysconfig.get_paths()['include'])")/Python.h" 2>&1
  python3 -c "import nanobind, cupy, torch; print('nanobind', nanobind.__version__, 'cupy', cupy.__version__, 'torch', torch.__version__)" 2>&1 | tail -1
  g++ --version | head -1
} >"$out/device.txt" 2>&1
cat "$out/device.txt"
status=0
export OMP_NUM_THREADS=8
RPYFMM_CUDA_SYNC=1 timeout 210 build/release/tests/pse/test_pse --gtest_filter='PseCuda*:PseRotationDevice*:PseBinPlan*' 2>&1 |
  tee "$out/test_pse_cuda.txt" | grep -E "^\[  (FAILED|PASSED|SKIPPED) |Failure|error" | head -40
[ "${PIPESTATUS[0]}" -eq 0 ] || status=1
grep -q "SKIPPED \]" "$out/test_pse_cuda.txt" && { echo "device-suite: a CUDA test was skipped"; status=1; }
# The BD device engine's tests that need a device (those of a machine without one skip here).
bd_device_filter='DeviceEngine.*:DeviceRestart.*:DeviceRun.*:DeviceIntegrator.*:DevicePse.*-DeviceEngine.RefusedWithoutDevice:DeviceRun.WithoutADevice*:DeviceIntegrator.CudaWithoutADevice*'
RPYFMM_EXPECT_CUDA=1 timeout 90 build/release/tests/bd/test_bd_device --gtest_filter="$bd_device_filter" 2>&1 |
  tee "$out/test_bd_device.txt" | grep -E "^\[  (FAILED|PASSED|SKIPPED) |Failure|error" | head -40
[ "${PIPESTATUS[0]}" -eq 0 ] || status=1
grep -q "SKIPPED \]" "$out/test_bd_device.txt" && { echo "device-suite: a BD device test was skipped"; status=1; }
# Kernel bounds and races of the BD device engine: one step refused by the guard, and a restart
# with rebuilds (binning, rows, forces, update). Exit 9: errors found (a failure); 124: timed out.
sanitizer=$(command -v compute-sanitizer || ls /usr/local/cuda*/bin/compute-sanitizer 2>/dev/null | head -1 || true)
if [ -n "$sanitizer" ]; then
  for tool in memcheck racecheck; do
    RPYFMM_EXPECT_CUDA=1 timeout 60 "$sanitizer" --tool "$tool" --error-exitcode 9 build/release/tests/bd/test_bd_device \
      --gtest_filter='DeviceEngine.BlowUpKeepsState:DeviceRestart.DeviceEngineContinuesBitForBit' \
      >"$out/sanitizer_bd_$tool.txt" 2>&1
    rc=$?
    echo "device-suite: compute-sanitizer $tool on test_bd_device rc=$rc (9: errors found, 124: timed out)"
    [ "$rc" -eq 0 ] || [ "$rc" -eq 124 ] || status=1
  done
else
  echo "device-suite: compute-sanitizer not found, BD device kernels not checked"
fi
# The Python device arrays (DLPack) on the CUDA PSE operator, where this machine's Python imports
# the carried extension (the same Python version as the build machine's) and has NumPy and pytest.
if PYTHONPATH=build/release/python python3 -c "import numpy, pytest, rpyfmm; assert rpyfmm.cuda_device_available()" \
  >"$out/test_python_device.txt" 2>&1; then
  PYTHONPATH=build/release/python timeout 120 python3 -m pytest -q -p no:cacheprovider -rs \
    tests/python/test_device_arrays.py tests/python/test_libmobility_device.py >>"$out/test_python_device.txt" 2>&1
  rc=$?
  tail -n 5 "$out/test_python_device.txt"
  [ "$rc" -eq 0 ] || status=1
else
  echo "device-suite: Python device tests not run: $(tail -n 1 "$out/test_python_device.txt")"
fi
echo "# CUDA tests: status $status at ${SECONDS} s"
unset OMP_NUM_THREADS
ctest_bin=$(command -v ctest || true)
if [ -n "$ctest_bin" ]; then
  # Eight tests at once with two OpenMP threads each (tests of the thread count set their own).
  # The whole script keeps within RPYFMM_DEVICE_BUDGET seconds (default 540, under one 600-second
  # device call): the suite gets at most 200 s of what is left, the benchmarks the rest.
  suite_budget=$(( ${RPYFMM_DEVICE_BUDGET:-540} - SECONDS - 60 ))
  [ "$suite_budget" -le "${RPYFMM_SUITE_BUDGET:-200}" ] || suite_budget=${RPYFMM_SUITE_BUDGET:-200}
  [ "$suite_budget" -ge 30 ] || suite_budget=30
  OMP_NUM_THREADS=2 OMP_WAIT_POLICY=PASSIVE timeout "$suite_budget" "$ctest_bin" \
    --test-dir build/release -j 8 --timeout 190 -E "python|package|pip" --output-on-failure >"$out/ctest.txt" 2>&1
  rc=$?
  tail -n 25 "$out/ctest.txt"
  [ "$rc" -eq 0 ] || status=1
else
  echo "device-suite: no ctest here" | tee "$out/ctest.txt"
  status=1
fi
echo "# suite: status $status at ${SECONDS} s"
# The GPU groups first, within 120 s: PSE on the device and the device BD engine at 1e6 particles
# against the CPU engine on the host's cores (bench/run.py groups pse-gpu and bd-gpu).
gpu_budget=$(( ${RPYFMM_DEVICE_BUDGET:-540} - SECONDS - 100 ))
[ "$gpu_budget" -le 120 ] || gpu_budget=120
if [ "$gpu_budget" -gt 20 ]; then
  RPYFMM_BENCH_COMMIT=$(cat gpu-kit/COMMIT) timeout "$gpu_budget" python3 bench/run.py --no-build --quick \
    --only bd-gpu pse-gpu --rounds 1 >>"$out/bench.txt" 2>&1
  echo "# bench bd-gpu pse-gpu: rc $? at ${SECONDS} s" | tee -a "$out/bench.txt"
fi
# One group at a time within RPYFMM_BENCH_BUDGET seconds (default 220) or what is left of
# RPYFMM_DEVICE_BUDGET, the longest (rpy) last, so that a budget spent keeps the groups already
# measured.
bench_budget=$(( ${RPYFMM_DEVICE_BUDGET:-540} - SECONDS ))
[ "$bench_budget" -le "${RPYFMM_BENCH_BUDGET:-220}" ] || bench_budget=${RPYFMM_BENCH_BUDGET:-220}
budget_end=$((SECONDS + bench_budget))
for group in fmm direct pse rpy; do
  left=$((budget_end - SECONDS))
  [ "$left" -gt 20 ] || { echo "# bench $group: skipped, ${left} s left" | tee -a "$out/bench.txt"; continue; }
  RPYFMM_BENCH_COMMIT=$(cat gpu-kit/COMMIT) timeout "$left" python3 bench/run.py --no-build --simd-levels \
    --levels avx512 avx2 --isa-rows --concurrent --only "$group" \
    --note "The host CPU of a lent GPU machine; programs built with GCC 12 on Debian 12 and carried" \
    >>"$out/bench.txt" 2>&1
  echo "# bench $group: rc $? at ${SECONDS} s" | tee -a "$out/bench.txt"
done
tar -czf "$out/results.tar.gz" bench/results/*.simd-levels.json bench/results/bd-gpu.json bench/results/pse-gpu.json \
  bench/README.md 2>/dev/null
exit $status

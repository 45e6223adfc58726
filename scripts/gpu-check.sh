#!/usr/bin/env bash
# Runs on the lent GPU machine, in the repository root, with gpu-kit/ carried
# (scripts/gpu-kit.sh builds it): the CPU-vs-GPU agreement tests of the CUDA PSE operator (host and
# device arrays, stage times),
# then the PSE Table I benchmark on the GPU at 8e3, 3.2e4, 2.5e5, 1e6 and 2e6 particles. Output goes to
# $OUT (or ./gpu-out) as test_pse_cuda.txt and bench_pse_cuda.csv (and sanitizer*.txt when
# compute-sanitizer is there and time is left), then bench_pse_cuda_bins.csv (the bin-edge sweep at
# RPYFMM_GPU_SWEEP sizes, default 32000 250000 1000000), then bench_bd.csv (whole BD steps with
# the mobility on the GPU and on the CPU cores). Sized for a few
# minutes of device time: pass fewer sizes as arguments to shorten it. Fails (non-zero exit) if
# the tests fail or skip (RPYFMM_EXPECT_CUDA: no usable device is an error, not a skip), or if
# the benchmark finds the GPU and CPU products apart by more than round-off (N <= 250000).
set -uo pipefail
cd "$(dirname "$0")/.."
source scripts/gpu-env.sh
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-8}"
nvidia-smi -L 2>&1 | tee "$out/device.txt"
echo "cuFFT from: $cufft_dir" | tee -a "$out/device.txt"
nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv >> "$out/device.txt" 2>&1
ldd gpu-kit/test_pse >> "$out/device.txt" 2>&1
RPYFMM_CUDA_SYNC=1 timeout 150 gpu-kit/test_pse --gtest_filter='PseCuda.*:PseCuda/*' 2>&1 | tee "$out/test_pse_cuda.txt"
test_rc=${PIPESTATUS[0]}
if grep -q "SKIPPED" "$out/test_pse_cuda.txt"; then echo "gpu-check: a CUDA test was skipped" >&2; test_rc=1; fi
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(8000 32000 250000 1000000 2000000)
# One process per size, each within what is left of the budget (RPYFMM_GPU_BUDGET seconds, default
# 360), so that a crash or a hang at one size keeps the rows of the others; the CSV header once.
budget="${RPYFMM_GPU_BUDGET:-360}"
bench_rc=0
first=1
sanitizer_done=0
run_sanitizer() {
  # compute-sanitizer memcheck and racecheck on the smallest CPU-vs-GPU test and two instances of
  # the bin kernels' test (a subgrid wrapping onto itself; crowded bins): kernel bounds and
  # shared-memory races; informative, does not change the exit status. Output: sanitizer*.txt.
  local sanitizer
  sanitizer=$(command -v compute-sanitizer || ls /usr/local/cuda*/bin/compute-sanitizer 2>/dev/null | head -1 || true)
  if [ -n "$sanitizer" ] && [ $((budget - SECONDS)) -gt 200 ]; then
    for tool in memcheck racecheck; do
      RPYFMM_CUDA_SYNC=1 timeout 90 "$sanitizer" --tool "$tool" --error-exitcode 9 gpu-kit/test_pse \
        --gtest_filter='PseCuda.SinglePrecisionGridsAgree:PseCuda/WindowBins.*/rectangular_float_edge12:PseCuda/WindowBins.*/clustered_double_edge4' \
        > "$out/sanitizer_$tool.txt" 2>&1
      echo "gpu-check: compute-sanitizer $tool rc=$? (9: errors found, 124: timed out)" | tee -a "$out/sanitizer.txt"
    done
  else
    echo "gpu-check: compute-sanitizer skipped (not found or no time left)" | tee -a "$out/sanitizer.txt"
  fi
  sanitizer_done=1
}
for n in "${sizes[@]}"; do
  # The sanitizer before the largest size (2e6 is beyond the issue's 1e6).
  if [ "$n" -gt 1000000 ] && [ "$sanitizer_done" -eq 0 ]; then run_sanitizer; fi
  left=$((budget - SECONDS))
  if [ "$left" -lt 30 ]; then echo "# N = $n: skipped, ${left} s of the budget left" | tee -a "$out/bench_pse_cuda.csv"; continue; fi
  if [ "$first" -eq 1 ]; then
    timeout "$left" gpu-kit/bench_pse --cuda "$n" 2>&1 | tee -a "$out/bench_pse_cuda.csv"
  else
    timeout "$left" gpu-kit/bench_pse --cuda "$n" 2>&1 | grep --line-buffered -v '^N,backend' | tee -a "$out/bench_pse_cuda.csv"
  fi
  rc=${PIPESTATUS[0]}
  first=0
  echo "# N = $n: bench_pse rc=$rc at ${SECONDS} s" | tee -a "$out/bench_pse_cuda.csv"
  [ "$rc" -eq 0 ] || bench_rc=$rc
done
[ "$sanitizer_done" -eq 1 ] || run_sanitizer
# The bin-edge sweep (bench_pse --bin-sweep) at RPYFMM_GPU_SWEEP sizes, if time is left.
for n in ${RPYFMM_GPU_SWEEP-32000 250000 1000000}; do
  left=$((budget - SECONDS))
  if [ "$left" -lt 30 ]; then echo "# sweep N = $n: skipped, ${left} s of the budget left" | tee -a "$out/bench_pse_cuda_bins.csv"; continue; fi
  header=$([ -s "$out/bench_pse_cuda_bins.csv" ] && echo '^N,backend' || echo '^$')  # the CSV header once
  timeout "$left" gpu-kit/bench_pse --cuda --bin-sweep "$n" 2>&1 | grep --line-buffered -v "$header" |
    tee -a "$out/bench_pse_cuda_bins.csv"
  echo "# sweep N = $n: bench_pse rc=${PIPESTATUS[0]} at ${SECONDS} s" | tee -a "$out/bench_pse_cuda_bins.csv"
done
# Whole BD steps (bench_bd steps: WCA spheres at phi = 0.05 in a periodic cube, sedimenting,
# PSE at tolerance 1e-3), the mobility on the GPU at RPYFMM_GPU_BD sizes (default 10000 100000
# 1000000), then on the host's CPU cores at RPYFMM_GPU_BD_CPU sizes (default 10000 100000), if
# time is left. Output: bench_bd.csv.
for device in cuda cpu; do
  if [ "$device" = cuda ]; then list="${RPYFMM_GPU_BD-10000 100000 1000000}"; else list="${RPYFMM_GPU_BD_CPU-10000 100000}"; fi
  for n in $list; do
    left=$((budget - SECONDS))
    if [ "$left" -lt 30 ]; then echo "# bd $device N = $n: skipped, ${left} s of the budget left" | tee -a "$out/bench_bd.csv"; continue; fi
    header=$([ -s "$out/bench_bd.csv" ] && echo '^method,' || echo '^$')
    threads=$([ "$device" = cpu ] && nproc || echo "$OMP_NUM_THREADS")  # the CPU runs on all host cores
    OMP_NUM_THREADS=$threads timeout "$left" gpu-kit/bench_bd steps --method pse --device "$device" --n "$n" --steps 5 2>&1 |
      grep --line-buffered -v "$header" | tee -a "$out/bench_bd.csv"
    echo "# bd $device N = $n: bench_bd rc=${PIPESTATUS[0]} at ${SECONDS} s" | tee -a "$out/bench_bd.csv"
  done
done
echo "gpu-check: tests rc=$test_rc, benchmark rc=$bench_rc (124: timed out; 3: GPU and CPU differ)"
[ "$test_rc" -eq 0 ] && [ "$bench_rc" -eq 0 ]

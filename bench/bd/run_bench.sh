#!/usr/bin/env bash
# Runs the BD benchmarks of RESULTS.md: throughput vs N at 1 and 2 threads
# (side by side in one run) and the neighbour-list rebuild comparison.
# Usage: bench/bd/run_bench.sh BUILD_DIR  (e.g. build-bd); keep machines quiet.
set -euo pipefail
B=${1:-build}/bench/bd/bench_bd
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-passive}  # shared machines: do not spin at barriers
for t in 1 2; do OMP_NUM_THREADS=$t $B steps --method none --n 1000,10000,100000 --steps 7 | sed "1!b;$( [ $t = 1 ] || echo d)"; done
for t in 1 2; do OMP_NUM_THREADS=$t $B steps --method direct --n 1000,3000 --steps 3 | sed 1d; done
for t in 1 2; do OMP_NUM_THREADS=$t $B steps --method direct --n 10000 --steps 1 | sed 1d; done
for t in 1 2; do OMP_NUM_THREADS=$t $B steps --method fmm --n 1000,3000,10000 --tol 1e-3 --steps 3 | sed 1d; done
for t in 1 2; do OMP_NUM_THREADS=$t $B steps --method fmm --n 100000 --tol 1e-3 --steps 1 | sed 1d; done
OMP_NUM_THREADS=2 $B neighbours --n 20000 --steps 300 --skin 1.0

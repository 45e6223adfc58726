#!/bin/bash
# Side-by-side benchmark of two builds of rpyfmm on the same machine, in one run, 1 thread:
# the Laplace FMM, FmmRpy, the direct kernels and BD steps, each case run by the previous and
# the new binaries in turn (so machine noise hits both alike). Raw output only; the tables in
# bench/README.md are made from it by hand.
#
# usage: bench/prev_vs_new.sh PREV_BENCH_DIR NEW_BENCH_DIR OUT_DIR [--big]
#   *_BENCH_DIR: a build's bench/ folder (with fmm/bench_fmm, rpy/bench_rpy_fmm,
#   direct/bench_direct, bd/bench_bd), e.g. build/release/bench of a worktree at the old commit.
#   --big adds FmmRpy at N = 1e6, 1e-6 (the issue-7 target row; minutes per binary).
set -euo pipefail
prev=$1 new=$2 out=$3 big=${4:-}
mkdir -p "$out"
export OMP_NUM_THREADS=1
run() {  # run TOOL ARGS...: both binaries, previous first, every output line tagged prev/new
  local tool=$1; shift
  for version in prev new; do
    local dir=$prev; [[ $version == new ]] && dir=$new
    "$dir/$tool" "$@" | sed "s/^/$version,/"
  done
}
{
  for dist in cube sphere; do for eps in 1e-3 1e-6 1e-9; do
    run fmm/bench_fmm --n 100000 --dist "$dist" --eps "$eps" --reps 3
  done; done
} | tee "$out/fmm.txt"
{
  for dist in suspension cylinder; do
    run rpy/bench_rpy_fmm "$dist" 10000,100000 1e-3,1e-6,1e-9 1 3
  done
  if [[ $big == --big ]]; then run rpy/bench_rpy_fmm suspension 1000000 1e-6 1 1; fi
} | tee "$out/rpy.txt"
run direct/bench_direct --n 8000 --threads 1 --reps 5 --kernel all | tee "$out/direct.txt"
{
  for method in direct fmm; do
    run bd/bench_bd steps --method "$method" --n 1000,2000,3000 --steps 3 --tol 1e-3
  done
} | tee "$out/bd.txt"

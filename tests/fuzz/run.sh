#!/usr/bin/env bash
# Builds the libFuzzer targets of rpyfmm's input readers with clang
# (-fsanitize=fuzzer,address,undefined) into build/fuzz and runs each for a bounded time on its
# seed corpus (tests/fuzz/corpus/<target>/, read only; new inputs go to build/fuzz/corpus/).
#
#   tests/fuzz/run.sh [target...]        targets: npy text config checkpoint particles (default all)
#   FUZZ_SECONDS=60                      time per target at most (-max_total_time)
#   FUZZ_SEED=1                          libFuzzer's seed; with it fixed, every run tries the same
#                                        inputs in the same order
#   FUZZ_RUNS=N                          inputs per target (default per target, below: as many
#                                        as a 2-core machine runs in well under FUZZ_SECONDS, so
#                                        that a clean run on one machine is a clean run on another)
#   RPYFMM_RELEASE_DIR=build/release     a CPU-only build whose librpyfmm_{bd,rpy,fmm}.a the config
#                                        and particles targets link (built here if missing)
#
# A crash, a sanitizer report, a leak, an input slower than 10 s or an allocation above 2 GB is a
# finding: libFuzzer stops, the input is saved under build/fuzz/artifacts/ and the script fails.
# Keep a fixed input in tests/fuzz/corpus/<target>/ so that every later run replays it.
# Without clang++ or its libFuzzer runtime (Debian: clang, libclang-rt-14-dev) it says so and
# exits 0.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
cxx=${FUZZ_CXX:-clang++}
seconds=${FUZZ_SECONDS:-60}
seed=${FUZZ_SEED:-1}
default_runs() {
  case $1 in
    npy|text) echo 200000 ;;
    config) echo 60000 ;;
    *) echo 6000 ;;  # checkpoint, particles: a few hundred inputs per second
  esac
}
release=${RPYFMM_RELEASE_DIR:-$root/build/release}
out=$root/build/fuzz
targets=("$@")
((${#targets[@]})) || targets=(npy text config checkpoint particles)
mkdir -p "$out/artifacts"

if ! command -v "$cxx" >/dev/null; then
  echo "fuzz: $cxx not found; skipped (scripts/install-deps.sh installs clang)"
  exit 0
fi
probe="$out/probe.cpp"
echo 'extern "C" int LLVMFuzzerTestOneInput(const unsigned char*, unsigned long) { return 0; }' >"$probe"
if ! "$cxx" -fsanitize=fuzzer "$probe" -o "$out/probe" 2>/dev/null; then
  echo "fuzz: $cxx has no libFuzzer runtime; skipped (Debian: libclang-rt-14-dev)"
  exit 0
fi

# -DNDEBUG as in the shipped build: toml++ 3.3's internal debug assertions fire on inputs its
# release parser refuses cleanly (e.g. corpus/config/regression-toml-dollar-key.toml).
flags=(-std=c++20 -g -O1 -DNDEBUG -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
       -I"$root/core/include" -I"$root/bd/include" -I"$root/rpy/include" -I"$root/fmm/include"
       -I"$root/apps/rpyfmm")
# The config and particle readers call into the BD library (mobility factory, force field):
# their own source file is compiled instrumented, the rest comes from the release archives.
library_libs() {
  if [ ! -f "$release/bd/librpyfmm_bd.a" ]; then
    cmake --build "$release" --target rpyfmm_bd >/dev/null
  fi
  echo "$release/bd/librpyfmm_bd.a $release/rpy/librpyfmm_rpy.a $release/fmm/librpyfmm_fmm.a" \
       "$release/core/librpyfmm_core.a" \
       "-lfftw3_omp -lfftw3f_omp -lfftw3 -lfftw3f -lgomp -lpthread"
}

build() {
  local target=$1
  local sources=("$root/tests/fuzz/fuzz_$target.cpp") libs=""
  case $target in
    npy|text) sources+=("$root/apps/rpyfmm/array_io.cpp") ;;
    checkpoint) sources+=("$root/bd/src/checkpoint.cpp") ;;
    config) sources+=("$root/bd/src/config.cpp"); libs=$(library_libs) ;;
    particles) sources+=("$root/bd/src/particles.cpp"); libs=$(library_libs) ;;
    *) echo "fuzz: unknown target '$target'" >&2; exit 2 ;;
  esac
  # shellcheck disable=SC2086  # $libs is a list of words
  "$cxx" "${flags[@]}" "${sources[@]}" $libs -o "$out/fuzz_$target"
}

for target in "${targets[@]}"; do
  if [[ $target == config || $target == particles ]] &&
     grep -q '^RPYFMM_USE_CUDA:BOOL=ON' "$release/CMakeCache.txt" 2>/dev/null; then
    echo "fuzz: $target skipped: $release is a CUDA build (set RPYFMM_RELEASE_DIR to a CPU-only one)"
    continue
  fi
  start=$(date +%s)
  build "$target"
  built=$(date +%s)
  mkdir -p "$out/corpus/$target"
  "$out/fuzz_$target" -seed="$seed" -runs="${FUZZ_RUNS:-$(default_runs "$target")}" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 \
    -max_len=8192 -print_final_stats=1 -artifact_prefix="$out/artifacts/$target-" \
    "$out/corpus/$target" "$root/tests/fuzz/corpus/$target" 2>"$out/$target.log" || {
    tail -n 40 "$out/$target.log"
    echo "fuzz: $target FAILED; the input is in $out/artifacts/ (log: $out/$target.log)"
    exit 1
  }
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$out/$target.log" | grep -o '[0-9]*$' || echo "?")
  echo "fuzz: $target ok: build $((built - start)) s, $runs inputs in $(($(date +%s) - built)) s"
done

#!/usr/bin/env python3
"""What a CPU without AVX-512 (or without AVX2) gets: the same benchmarks run at each
instruction-set level this machine has (RPYFMM_SIMD, docs/reproducibility.md), side by side in
one run, one thread, medians of --reps runs.

Rows: the Laplace FMM (N = 1e6, eps 1e-6, potential + gradient + Hessian), the direct Laplace
kernel (N = 2e4), FmmRpy (N = 1e6, tolerance 1e-6; and one Laplace FMM on the same points) and
the PSE product and sampler (N = 1e5, tolerance 1e-3).

    python3 bench/simd_levels.py [--build build/release] [--reps 3] [--quick]

Writes bench/results/simd_levels.json (machine, ISA, commit, date, every run) and prints a
Markdown table. --quick: sizes / 10, for a smoke run.
"""
import argparse
import csv
import datetime
import io
import json
import os
import platform
import statistics
import subprocess
import sys

LEVELS = ["avx512", "avx2", "scalar"]


def machine():
    model = platform.processor()
    flags = ""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name") and model in ("", platform.machine()):
                    model = line.split(":", 1)[1].strip()
                if line.startswith("flags"):
                    flags = line
                    break
    except OSError:
        pass
    isa = "avx512" if " avx512f" in flags else "avx2" if " avx2" in flags else "baseline"
    return {"cpu": model, "isa": isa, "cores": os.cpu_count()}


def commit():
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def run(cmd, level):
    env = dict(os.environ, RPYFMM_SIMD=level, OMP_NUM_THREADS="1")
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True).stdout
    return [line for line in out.splitlines() if line and not line.startswith("#")]


def fmm(build, n, level):
    lines = run([f"{build}/bench/fmm/bench_fmm", "--n", str(n), "--eps", "1e-6", "--reps", "1"], level)
    return json.loads(lines[-1])["eval_s"]


def direct(build, n, level):
    rows = list(csv.DictReader(io.StringIO("\n".join(
        run([f"{build}/bench/direct/bench_direct", "--n", str(n), "--threads", "1", "--reps", "3", "--kernel",
             "laplace"], level)))))
    row = [r for r in rows if r["outputs"] == "pot+grad+hess"][-1]
    return float(row["median_s"])


def rpy(build, n, level):
    rows = list(csv.DictReader(io.StringIO("\n".join(
        run([f"{build}/bench/rpy/bench_rpy_fmm", "cube", str(n), "1e-6", "1", "1"], level)))))
    return float(rows[-1]["rpy_s"]), float(rows[-1]["laplace1_s"])


def pse(build, n, level):
    rows = list(csv.DictReader(io.StringIO("\n".join(
        run([f"{build}/bench/pse/bench_pse", "--quick", str(n)], level)))))
    return float(rows[-1]["MF_s"]), float(rows[-1]["sample_s"])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default="build/release")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    scale = 10 if args.quick else 1
    info = machine()
    levels = LEVELS[LEVELS.index(info["isa"]) if info["isa"] in LEVELS else 2:]
    benches = {
        "Laplace FMM": lambda lv: {"s": fmm(args.build, 1000000 // scale, lv)},
        "direct kernel": lambda lv: {"s": direct(args.build, 20000 // scale, lv)},
        "FmmRpy": lambda lv: dict(zip(("s", "laplace_s"), rpy(args.build, 1000000 // scale, lv))),
        "PSE": lambda lv: dict(zip(("s", "sample_s"), pse(args.build, 100000 // scale, lv))),
    }
    sizes = {"Laplace FMM": "N = 1e6, eps 1e-6, pot+grad+Hess", "direct kernel": "N = 2e4, pot+grad+Hess",
             "FmmRpy": "N = 1e6, tolerance 1e-6", "PSE": "N = 1e5, tolerance 1e-3, M F"}
    results = {}
    for name, bench in benches.items():
        for level in levels:
            runs = [bench(level) for _ in range(args.reps)]
            results.setdefault(name, {})[level] = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
            print(f"# {name} at {level}: {results[name][level]}", file=sys.stderr)
    record = {"machine": info, "commit": commit(), "date": datetime.date.today().isoformat(), "threads": 1,
              "reps": args.reps, "quick": args.quick, "results": results}
    os.makedirs("bench/results", exist_ok=True)
    with open("bench/results/simd_levels.json", "w") as f:
        json.dump(record, f, indent=1)
    print(f"{info['cpu']} ({info['isa']}, {info['cores']} cores), commit {record['commit']}, "
          f"{record['date']}, 1 thread, median of {args.reps}\n")
    print("| benchmark | size | " + " | ".join(f"{lv} (s)" for lv in levels) + " | " +
          " | ".join(f"{lv} / {levels[0]}" for lv in levels[1:]) + " |")
    print("|---|---|" + "---|" * (2 * len(levels) - 1))
    for name in benches:
        t = [results[name][lv]["s"] for lv in levels]
        print(f"| {name} | {sizes[name]} | " + " | ".join(f"{x:.3g}" for x in t) + " | " +
              " | ".join(f"{x / t[0]:.2f}" for x in t[1:]) + " |")


if __name__ == "__main__":
    main()

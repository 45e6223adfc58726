#!/usr/bin/env python3
"""Performance model of DistributedLaplaceFmm (docs/mpi.md, "Scaling and a performance model").

Fitted from the measurements of bench_mpi_fmm in essential_sets.jsonl (one JSON line per run; the first
line names the commit, date and machine) and prints the predicted time per evaluation for N = 1e8 on
64 ... 4096 ranks and for the dissertation's case, 1.5e7 sources on 12,288 ranks.

Lengths are in mean particle spacings (density 1): a rank's n own sources fill a region of side
n^(1/3) in a domain of side N^(1/3). Per evaluation, on the slowest rank:
  halo(n)     = (n^(1/3) + s)^3 - n        the sources within a shell of thickness s around the region
                                           (cells too close or too small to compress);
  nodes(n, N) = c r^2 log2(N^(1/3) / r)    equivalent charges: a surface of compressed cells around the
                with r = n^(1/3) + s        shell on every level out to the domain;
  E           = n + halo + nodes           the serial FMM's sources on the rank;
  T           = a E + b n                  the serial FMM (source work a per source, target work b per
                + bytes / beta              target) + the three exchanges (8 bytes per halo source and
                + 3 (P - 1) lambda          node, 88 per own source: its charge and 10 results).
"""
import json
import math
import statistics
import sys
from pathlib import Path

BETA = 1e9  # bytes per second per rank (assumed network: ~32 ranks sharing a ~32 GB/s node link)
LAMBDA = 2e-6  # seconds per message (assumed; each all-to-all visits the P - 1 other ranks)


def load(path: Path) -> list[dict]:
    lines = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return lines[1:]  # the first line names the measurement


def fit(rows: list[dict]) -> dict:
    """s and c from the runs on 16 or more ranks (regions mostly away from the domain's boundary); a and b from
    the run on 1 rank (a + b) and the oversubscribed runs' CPU time per rank (wall time x cores / ranks)."""
    interior = [r for r in rows if r["ranks"] >= 16]
    s_values, c_values, a_values = [], [], []
    one = next(r for r in rows if r["ranks"] == 1)
    a_plus_b = one["eval_work_fmm_s"] / one["N"]
    for r in interior:
        n = r["N"] / r["ranks"]
        halo, nodes = r["halo"] / r["ranks"], r["nodes"] / r["ranks"]
        s = (n + halo) ** (1 / 3) - n ** (1 / 3)
        rad = n ** (1 / 3) + s
        s_values.append(s)
        c_values.append(nodes / (rad**2 * math.log2(r["N"] ** (1 / 3) / rad)))
        cpu = r["eval_work_fmm_s"] * 2 / r["ranks"]  # 2 cores shared by the ranks
        a_values.append((cpu - a_plus_b * n) / (r["essential_max"] - n))
    a = statistics.median(a_values)
    return {"s": statistics.median(s_values), "c": statistics.median(c_values), "a": a, "b": a_plus_b - a}


def predict(m: dict, big_n: float, ranks: int) -> dict:
    n = big_n / ranks
    rad = n ** (1 / 3) + m["s"]
    halo = rad**3 - n
    nodes = m["c"] * rad**2 * max(math.log2(big_n ** (1 / 3) / rad), 0.0)
    e = min(n + halo + nodes, big_n)
    compute = m["a"] * e + m["b"] * n
    bytes_ = 8 * (e - n) + 88 * n
    comm = bytes_ / BETA + 3 * (ranks - 1) * LAMBDA
    serial = (m["a"] + m["b"]) * big_n
    return {"N": big_n, "P": ranks, "n": n, "E": e, "E/n": e / n, "compute_s": compute, "comm_s": comm,
            "T_s": compute + comm, "efficiency": serial / (ranks * (compute + comm))}


def main() -> None:
    path = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("essential_sets.jsonl")
    m = fit(load(path))
    print("fit: s = {s:.1f} spacings, c = {c:.1f}, a = {a:.2e} s, b = {b:.2e} s".format(**m))
    print("| N | P | n per rank | E per rank | E / n | compute s | comm s | T s | efficiency |")
    print("|---|---|---|---|---|---|---|---|---|")
    for big_n, ranks in [(1e8, p) for p in (64, 256, 1024, 4096)] + [(1.5e7, 12288)]:
        r = predict(m, big_n, ranks)
        print(f"| {big_n:.1e} | {ranks} | {r['n']:.3g} | {r['E']:.3g} | {r['E/n']:.1f} | {r['compute_s']:.3g} | "
              f"{r['comm_s']:.2g} | {r['T_s']:.3g} | {100 * r['efficiency']:.0f} % |")


if __name__ == "__main__":
    main()

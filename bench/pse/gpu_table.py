#!/usr/bin/env python3
"""Turns `bench_pse --cuda` output (bench_pse_cuda.csv from scripts/gpu-check.sh) into the
markdown tables of bench/pse/RESULTS.md and checks the issue's GPU targets.

usage: python3 bench/pse/gpu_table.py gpu-out/bench_pse_cuda.csv

Targets ([PSE] Table I setup, N ~ 1e6): >= 50e6 particle-timesteps per second for M F and
>= 30e6 for the split sampler M^1/2 z, i.e. 10x the paper's K40 figures. Each target is judged
on the defaults' row (the first row printed for each N) at the N closest to 1e6, once with host
arrays in and out (transfers counted) and once with device arrays (apply_device /
sample_device). Exit status 0 when both targets are met with device arrays, 1 otherwise (2: no
rows).
"""
import csv
import sys

TARGET_MF = 50e6
TARGET_SAMPLE = 30e6


def read_rows(path: str) -> list[dict]:
    with open(path) as f:
        lines = [line for line in f if line.strip() and not line.startswith("#")]
    return list(csv.DictReader(lines))


def fmt(value: str, scale: float = 1.0, digits: int = 3) -> str:
    v = float(value)
    return "-" if v < 0 else f"{v * scale:.{digits}g}"


def main(path: str) -> int:
    rows = read_rows(path)
    if not rows:
        print("no benchmark rows in", path)
        return 2
    print("| N | wave | lists | bin | transfers | grid, P | set_positions (s) | M F (s) | M F PTPS | M F dev PTPS |"
          " sample (s) | sample PTPS | sample dev PTPS | sample / M F | its | BD step (s) | diff from CPU |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['N']} | {r['wave']} | {r['lists']} | {r.get('bin', '-')} | {r.get('transfers', 'pageable')} | {r['grid']}, {r['P']} | {fmt(r['set_positions_s'])} |"
              f" {fmt(r['MF_s'])} | {fmt(r['MF_PTPS'])} | {fmt(r['MF_dev_PTPS'])} | {fmt(r['sample_s'])} |"
              f" {fmt(r['sample_PTPS'])} | {fmt(r['sample_dev_PTPS'])} | {r['sample_over_MF']} |"
              f" {r['split_iters']} | {fmt(r.get('step_s') or '-1')} | {fmt(r['rel_diff_cpu'])} |")
    print()
    print("Stages per M F and per sample (ms):")
    print()
    print("| N | wave | lists | bin | transfers | transfer | real space | spread | FFTs | scale | interpolate | sample: Lanczos |"
          " sample: wave noise |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        cells = [fmt(r[k], 1e3) for k in ("MF_transfer_s", "MF_real_s", "MF_spread_s", "MF_fft_s", "MF_scale_s",
                                          "MF_interp_s", "sample_lanczos_s", "sample_wave_s")]
        print(f"| {r['N']} | {r['wave']} | {r['lists']} | {r.get('bin', '-')} | {r.get('transfers', 'pageable')} | "
              + " | ".join(cells) + " |")
    print()
    n_target = min({int(r["N"]) for r in rows}, key=lambda n: abs(n - 1_000_000))
    at = [r for r in rows if int(r["N"]) == n_target]
    met = True
    for label, host_key, dev_key, target in (("M F", "MF_PTPS", "MF_dev_PTPS", TARGET_MF),
                                             ("M^1/2 z", "sample_PTPS", "sample_dev_PTPS", TARGET_SAMPLE)):
        row = at[0]  # the defaults (bench_pse prints them first for each N)
        host, dev = float(row[host_key]), float(row[dev_key])
        met = met and dev >= target
        print(f"- {label} at N = {n_target} ({row['wave']} grids, {row['lists']} lists, bin {row.get('bin', '-')}):"
              f" host arrays {host:.3g} PTPS, device arrays {dev:.3g} PTPS; target {target:.0e}:"
              f" {'met' if dev >= target else 'NOT met'} (device arrays),"
              f" {'met' if host >= target else 'not met'} (host arrays)")
    return 0 if met else 1


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))

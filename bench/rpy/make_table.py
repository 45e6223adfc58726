#!/usr/bin/env python3
"""Markdown tables (dissertation Tables 3.1-3.6 layout) from results_rpy.csv and
results_stfmm3d.csv. usage: make_table.py results_rpy.csv results_stfmm3d.csv"""
import csv
import sys


def main():
    rpy = list(csv.DictReader(open(sys.argv[1])))
    st = {(r["dist"], int(r["N"]), float(r["eps"])): float(r["seconds"]) for r in csv.DictReader(open(sys.argv[2]))}
    print("| dist | N | eps | threads | FmmRpy [s] | rel. l2 error | one Laplace FMM [s] | RPY / Laplace | direct [s] | "
          "speed-up vs direct | fmm3dpy stfmm3d [s] (1 thr) | stfmm3d / FmmRpy | levels | leaves | near field [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rpy:
        key = (r["dist"], int(r["N"]), float(r["eps"]))
        s = st.get(key)
        peer = f"{s:.2f}" if s is not None else "—"
        ratio = f"{s / float(r['rpy_s']):.1f}x" if s is not None and r["threads"] == "1" else "—"
        direct = f"{float(r['direct_s']):.2f}" + (" (extrap.)" if r["direct_kind"] == "extrapolated" else "")
        print(f"| {r['dist']} | {int(r['N']):.0e} | {r['eps']} | {r['threads']} | {float(r['rpy_s']):.3f} | "
              f"{float(r['rel_l2_err']):.1e} | {float(r['laplace1_s']):.3f} | {float(r['ratio_rpy_laplace']):.2f} | "
              f"{direct} | {float(r['speedup_vs_direct']):.1f} | {peer} | {ratio} | {r['levels']} | {r['leaves']} | "
              f"{float(r['near_s']):.3f} |")


if __name__ == "__main__":
    main()

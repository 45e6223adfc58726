#!/usr/bin/env python3
"""Markdown table (dissertation Tables 2.1-2.12 layout) from compare_fmm3d.py JSON lines.

Usage: make_table.py results.jsonl [...]
"""
import json, sys

rows = [json.loads(l) for f in sys.argv[1:] for l in open(f) if l.strip()]
print("| N | dist | eps | thr | levels | boxes | leaf | p | rpyfmm eval [s] | rpyfmm setup [s] | fmm3dpy [s] | ratio eval | ratio incl. setup "
      "| err pot / grad / Hess (rpyfmm) | err pot / grad / Hess (fmm3dpy) | peak RSS MB rpyfmm / fmm3dpy |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for r in rows:
    o, f = r["rpyfmm"], r["fmm3d"]
    print(f"| {r['n']} | {r['dist']} | {r['eps']} | {r['threads']} | {o['levels']} | {o['boxes']} | {o['leaf']} | {o['p']} "
          f"| {r['rpyfmm_s']:.3f} | {r['rpyfmm_setup_s']:.3f} | {r['fmm3d_s']:.3f} | {r['fmm3d_s'] / r['rpyfmm_s']:.2f} "
          f"| {r['ratio_fmm3d_over_rpyfmm']:.2f} "
          f"| {o['err_pot']:.1e} / {o['err_grad']:.1e} / {o['err_hess']:.1e} "
          f"| {f['err_pot']:.1e} / {f.get('err_grad', 0):.1e} / {f.get('err_hess', 0):.1e} "
          f"| {o['peak_rss_mb']:.0f} / {f['peak_rss_mb']:.0f} |")
print()
print("Per-stage breakdown of rpyfmm (seconds):\n")
stages = ["tree", "p2m", "m2m", "m2l", "l2l", "x_p2l", "l2p", "wx_far", "p2p", "sort", "total"]
print("| N | dist | eps | thr | " + " | ".join(stages) + " |")
print("|" + "---|" * (4 + len(stages)))
for r in rows:
    st = r["rpyfmm"]["stages"]
    print(f"| {r['n']} | {r['dist']} | {r['eps']} | {r['threads']} | " + " | ".join(f"{st.get(k, 0):.3f}" for k in stages) + " |")

#!/usr/bin/env python3
"""Iteration growth of the square-root samplers from bench_sqrt CSV output.

usage: plot_sqrt.py OUT.svg results_direct.csv [results_fmm.csv ...]

Fits iterations ~ C N^p (least squares in log-log, 1-thread rows) for every
(operator, tolerance, method) and prints the exponents as a Markdown table;
draws iterations versus N (log-log) as a dependency-free SVG.
"""
import csv
import math
import sys
from collections import defaultdict


def fit(xs, ys):
    lx = [math.log(x) for x in xs]
    ly = [math.log(y) for y in ys]
    n = len(lx)
    mx, my = sum(lx) / n, sum(ly) / n
    sxx = sum((a - mx) ** 2 for a in lx)
    p = sum((a - mx) * (b - my) for a, b in zip(lx, ly)) / sxx
    return p, math.exp(my - p * mx)


def main():
    out = sys.argv[1]
    series = defaultdict(list)
    for path in sys.argv[2:]:
        with open(path) as f:
            for row in csv.DictReader(f):
                if row["threads"] != "1":
                    continue
                key = (row["operator"], row["tol"], row["method"])
                series[key].append((int(row["N"]), float(row["iterations"])))
    print("| operator | tol | method | N range | iterations | exponent p (iters ~ N^p) |")
    print("|---|---|---|---|---|---|")
    for key in sorted(series):
        pts = sorted(series[key])
        if len(pts) < 2:
            continue
        p, _ = fit([a for a, _ in pts], [b for _, b in pts])
        its = ", ".join(f"{b:.0f}" for _, b in pts)
        print(f"| {key[0]} | {key[1]} | {key[2]} | {pts[0][0]}-{pts[-1][0]} | {its} | {p:.2f} |")

    # SVG, log-log axes.
    W, H, L, R, T, B = 640, 420, 70, 200, 20, 50
    allx = [a for v in series.values() for a, _ in v]
    ally = [b for v in series.values() for _, b in v]
    x0, x1 = math.log10(min(allx)) - 0.05, math.log10(max(allx)) + 0.05
    y0, y1 = math.log10(min(ally)) - 0.1, math.log10(max(ally)) + 0.1
    sx = lambda x: L + (math.log10(x) - x0) / (x1 - x0) * (W - L - R)
    sy = lambda y: H - B - (math.log10(y) - y0) / (y1 - y0) * (H - T - B)
    colors = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf"]
    svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="11">',
           f'<rect width="{W}" height="{H}" fill="white"/>',
           f'<line x1="{L}" y1="{H-B}" x2="{W-R}" y2="{H-B}" stroke="black"/>',
           f'<line x1="{L}" y1="{T}" x2="{L}" y2="{H-B}" stroke="black"/>']
    for e in range(math.ceil(x0), math.floor(x1) + 1):
        for m in (1, 2, 5):
            v = m * 10 ** e
            if x0 <= math.log10(v) <= x1:
                svg.append(f'<text x="{sx(v):.1f}" y="{H-B+15}" text-anchor="middle">{v:g}</text>')
    for e in range(math.floor(y0), math.ceil(y1) + 1):
        for m in (1, 2, 5):
            v = m * 10 ** e
            if y0 <= math.log10(v) <= y1:
                svg.append(f'<text x="{L-6}" y="{sy(v)+4:.1f}" text-anchor="end">{v:g}</text>')
                svg.append(f'<line x1="{L}" y1="{sy(v):.1f}" x2="{W-R}" y2="{sy(v):.1f}" stroke="#ddd"/>')
    svg.append(f'<text x="{(L+W-R)/2}" y="{H-12}" text-anchor="middle">N (particles)</text>')
    svg.append(f'<text x="16" y="{(T+H-B)/2}" transform="rotate(-90 16 {(T+H-B)/2})" text-anchor="middle">'
               'iterations / degree</text>')
    for i, key in enumerate(sorted(series)):
        pts = sorted(series[key])
        c = colors[i % len(colors)]
        dash = ' stroke-dasharray="5,3"' if key[2] == "chebyshev" else ""
        path = " ".join(f"{sx(a):.1f},{sy(b):.1f}" for a, b in pts)
        svg.append(f'<polyline points="{path}" fill="none" stroke="{c}" stroke-width="1.5"{dash}/>')
        for a, b in pts:
            svg.append(f'<circle cx="{sx(a):.1f}" cy="{sy(b):.1f}" r="2.5" fill="{c}"/>')
        ly = T + 14 * i + 10
        svg.append(f'<line x1="{W-R+10}" y1="{ly}" x2="{W-R+30}" y2="{ly}" stroke="{c}" stroke-width="1.5"{dash}/>')
        svg.append(f'<text x="{W-R+34}" y="{ly+4}">{key[0]} {key[2]} tol {key[1]}</text>')
    svg.append("</svg>")
    with open(out, "w") as f:
        f.write("\n".join(svg) + "\n")


if __name__ == "__main__":
    main()

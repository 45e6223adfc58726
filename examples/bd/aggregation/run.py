#!/usr/bin/env python3
"""Aggregation with the 36-18 potential: three densities without HI (as in
Tran et al. (2015), Fig. 3) and one small system with and without HI (PSE), all derived from
aggregation.toml. Each case runs in four pieces of 10x more steps and 10x
sparser frames (100 frames a decade: a log-spaced time axis); the pieces are
bitwise identical over their common steps (noise keyed by step), so together
they are one trajectory.

    OMP_NUM_THREADS=1 python3 examples/bd/aggregation/run.py [--out DIR] [--quick]
    python3 examples/bd/aggregation/plot.py [--out DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import _analysis as an  # noqa: E402

BASE = HERE / "aggregation.toml"
DECADES = 4  # pieces of steps/1000, /100, /10, /1


def box(count: int, phi: float) -> float:
    return float(np.cbrt(count * 4.0 / 3.0 * np.pi / phi))


CASES = {  # name: (count, volume fraction, mobility, steps)
    "fd_phi05": (1000, 0.05, "none", 100000),
    "fd_phi10": (1000, 0.10, "none", 100000),
    "fd_phi20": (1000, 0.20, "none", 100000),
    "fd_n300": (300, 0.10, "none", 100000),
    "hi_n300": (300, 0.10, "pse", 30000),
}


def main() -> int:
    args = an.script_args(__doc__, HERE, only=dict(nargs="*", default=list(CASES),
                                                                 help="cases to run (default: all)"))
    total = 0.0
    for name in args.only:
        count, phi, method, steps = CASES[name]
        L = round(box(count, phi), 3)
        for k in range(DECADES):
            piece = steps // 10 ** (DECADES - 1 - k)
            cfg = an.derive_config(BASE, args.out / name / f"piece{k}.toml", {
                "system.box": [L, L, L], "particles.count": count, "mobility.method": method,
                "integrator.steps": piece, "output.trajectory_every": max(1, piece // 100),
                "output.log_every": max(1, piece // 100)})
            total += an.run_bd(cfg, args.out / name / f"piece{k}", threads=args.threads)
    print(f"done in {total:.0f} s; now: python3 {HERE / 'plot.py'} --out {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""The bimodal example with free draining (bimodal.toml as is) and with RPY
hydrodynamics (mobility.method = "direct"), same initial state and noise seed.

    OMP_NUM_THREADS=1 python3 examples/bd/bimodal/run.py [--out DIR]
    python3 examples/bd/bimodal/plot.py [--out DIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import _analysis as an  # noqa: E402

BASE = HERE / "bimodal.toml"
CASES = {"fd": "none", "hi": "direct"}


def main() -> int:
    args = an.script_args(__doc__, HERE, steps=dict(type=int, default=None,
                                                             help="override integrator.steps (default: the config's)"))
    total = 0.0
    for name, method in CASES.items():
        cfg = an.derive_config(BASE, args.out / f"{name}.toml", {
            "particles.file": str(HERE / "particles.txt"), "mobility.method": method})
        total += an.run_bd(cfg, args.out / name, steps=args.steps, threads=args.threads)
    print(f"done in {total:.0f} s; now: python3 {HERE / 'plot.py'} --out {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

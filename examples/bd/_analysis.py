"""Shared helpers for the examples under examples/bd/: run `rpyfmm bd` on a
config with a few keys overridden, read its outputs (extended-XYZ trajectory,
CSV log), and the analysis pieces more than one example needs (clusters,
the RPY pair mobility, least-squares fits, matplotlib import).

Only numpy is required to run and analyse; matplotlib only to plot. The
rpyfmm binary is taken from $RPYFMM, else from the usual build folders
(build-ex, build/release, build), else from PATH.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]  # the repository


def pyplot():
    """matplotlib.pyplot with a non-interactive backend, or exit with a clear message."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        sys.exit("error: matplotlib is needed for the plot: python3 -m pip install matplotlib")
    return plt


def script_args(doc: str, here: Path, png: str | None = None, **options: dict) -> argparse.Namespace:
    """Command line of a run.py (png None: --out, --threads) or plot.py (--out, --png) script;
    options: more of them, name=add_argument keywords (e.g. only={"nargs": "*"} for --only)."""
    p = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    for name, kw in options.items():
        p.add_argument("--" + name, **kw)
    p.add_argument("--out", type=Path, default=here / "out", help="run.py output folder (default: %(default)s)")
    if png is None:
        p.add_argument("--threads", type=int, default=None, help="OpenMP threads (default: OMP_NUM_THREADS)")
    else:
        p.add_argument("--png", type=Path, default=here / png, help="plot file (default: %(default)s)")
    return p.parse_args()


def figure(*args, **kw):
    """(pyplot, figure, axes) for a plot script; exits clearly without matplotlib."""
    plt = pyplot()
    fig, axes = plt.subplots(*args, **kw)
    return plt, fig, axes


def save_figure(fig, path: Path) -> int:
    """Lay out, save at 110 dpi and say where; returns 0 (the script's exit status)."""
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")
    return 0


def rpyfmm_binary() -> str:
    """Path of the rpyfmm command-line tool (see the module docstring)."""
    if os.environ.get("RPYFMM"):
        return os.environ["RPYFMM"]
    for build in ("build-ex", "build/release", "build"):
        exe = ROOT / build / "apps" / "rpyfmm"
        if exe.is_file() and os.access(exe, os.X_OK):
            return str(exe)
    exe = shutil.which("rpyfmm")
    if exe:
        return exe
    sys.exit("error: rpyfmm binary not found: build it (README.md) or set RPYFMM=/path/to/rpyfmm")


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(v)


def derive_config(base: Path, out: Path, overrides: dict[str, object]) -> Path:
    """Write a copy of the TOML config `base` to `out` with keys replaced.

    `overrides` maps "section.key" (the first table of that name, [s] or [[s]])
    to a value; a key the section lacks is added at its top. Comments and all
    other lines are kept, so the derived file reads like the base one."""
    lines = Path(base).read_text().splitlines()
    for dotted, value in overrides.items():
        section, key = dotted.split(".", 1)
        header = next((i for i, l in enumerate(lines) if re.match(rf"^\s*\[\[?{re.escape(section)}\]\]?\s*(#.*)?$", l)),
                      None)
        if header is None:
            lines += ["", f"[{section}]"]
            header = len(lines) - 1
        end = next((i for i in range(header + 1, len(lines)) if re.match(r"^\s*\[", lines[i])), len(lines))
        new = f"{key} = {_toml_value(value)}"
        for i in range(header + 1, end):
            m = re.match(rf"^\s*{re.escape(key)}\s*=\s*[^#]*?(\s*#.*)?$", lines[i])
            if m:
                lines[i] = new + (m.group(1) or "")
                break
        else:
            lines.insert(header + 1, new)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")
    return out


def run_bd(config: Path, out_dir: Path, steps: int | None = None, threads: int | None = None) -> float:
    """Run `rpyfmm bd --config config --out-dir out_dir` (quiet); returns wall seconds."""
    cmd = [rpyfmm_binary(), "bd", "--config", str(config), "--out-dir", str(out_dir), "--quiet"]
    if steps is not None:
        cmd += ["--steps", str(steps)]
    if threads is not None:
        cmd += ["--threads", str(threads)]
    t0 = time.perf_counter()
    print("  $", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)
    return time.perf_counter() - t0


def read_log(path: Path) -> dict[str, np.ndarray]:
    """The CSV log as {column: array}."""
    data = np.genfromtxt(path, delimiter=",", names=True)
    return {name: np.atleast_1d(data[name]) for name in data.dtype.names}


class Trajectory:
    """Frames of an extended-XYZ trajectory: times, steps, species (of frame 0),
    radii (N,), positions (F, N, 3), box (3,) or None (open geometry)."""

    def __init__(self, path: Path, every: int = 1):
        text = Path(path).read_text().splitlines()
        times, steps, frames = [], [], []
        self.species, self.radii, self.box = None, None, None
        i, k = 0, 0
        while i < len(text):
            n = int(text[i])
            header = text[i + 1]
            if k % every == 0:
                times.append(float(re.search(r"Time=(\S+)", header).group(1)))
                steps.append(int(re.search(r"Step=(\S+)", header).group(1)))
                cols = np.array(" ".join(text[i + 2 : i + 2 + n]).split()).reshape(n, -1)
                frames.append(cols[:, 1:4].astype(float))
                if self.species is None:
                    self.species = cols[:, 0]
                    self.radii = cols[:, 4].astype(float)
                    lat = re.search(r'Lattice="([^"]+)"', header)
                    if lat:
                        m = np.array([float(x) for x in lat.group(1).split()]).reshape(3, 3)
                        self.box = np.diag(m).copy()
            i += n + 2
            k += 1
        self.times = np.array(times)
        self.steps = np.array(steps)
        self.positions = np.array(frames)


def clusters(x: np.ndarray, radii: np.ndarray, factor: float, box=None) -> np.ndarray:
    """Cluster labels (0..K-1, per particle): i and j are linked when
    |x_i - x_j| < factor (a_i + a_j) (minimum image when `box` is given)."""
    n = len(x)
    r2 = np.zeros((n, n))
    for k in range(3):
        d = np.subtract.outer(x[:, k], x[:, k])
        if box is not None:
            d -= box[k] * np.rint(d / box[k])
        r2 += d * d
    close = r2 < (factor * np.add.outer(radii, radii)) ** 2
    i, j = np.nonzero(np.triu(close, 1))
    parent = list(range(n))

    def root(k):
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    for a, b in zip(i.tolist(), j.tolist()):
        ra, rb = root(a), root(b)
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    return np.unique([root(k) for k in range(n)], return_inverse=True)[1]


def rpy_pair(r: np.ndarray, ai: np.ndarray, aj: np.ndarray, eta: float = 1.0):
    """RPY pair mobility for separations r (>0), radii ai, aj: the coefficients
    (f, g) of mu_ij = f I + g rhat rhat, all overlap regimes (Zuk, Wajnryb,
    Mizerski & Szymczak, J. Fluid Mech. 741 (2014) R5)."""
    r, ai, aj = np.broadcast_arrays(np.asarray(r, float), np.asarray(ai, float), np.asarray(aj, float))
    f, g = np.empty_like(r), np.empty_like(r)
    far = r > ai + aj
    inside = r <= np.abs(ai - aj)
    mid = ~far & ~inside
    s2 = ai**2 + aj**2
    f[far] = (1 + s2[far] / (3 * r[far] ** 2)) / (8 * np.pi * eta * r[far])
    g[far] = (1 - s2[far] / r[far] ** 2) / (8 * np.pi * eta * r[far])
    f[inside] = 1 / (6 * np.pi * eta * np.maximum(ai[inside], aj[inside]))
    g[inside] = 0.0
    rm, am, bm = r[mid], ai[mid], aj[mid]
    pre = 1 / (6 * np.pi * eta * am * bm * 32 * rm**3)
    f[mid] = pre * (16 * rm**3 * (am + bm) - ((am - bm) ** 2 + 3 * rm**2) ** 2)
    g[mid] = pre * 3 * ((am - bm) ** 2 - rm**2) ** 2
    return f, g


def rpy_matrix(x: np.ndarray, radii: np.ndarray, eta: float = 1.0) -> np.ndarray:
    """The dense 3N x 3N RPY mobility matrix of positions x (N,3)."""
    n = len(x)
    d = x[:, None, :] - x[None, :, :]
    r = np.linalg.norm(d, axis=-1)
    np.fill_diagonal(r, 1.0)
    f, g = rpy_pair(r, radii[:, None], radii[None, :], eta)
    rhat = d / r[..., None]
    m = f[..., None, None] * np.eye(3) + g[..., None, None] * rhat[..., :, None] * rhat[..., None, :]
    idx = np.arange(n)
    m[idx, idx] = np.eye(3) / (6 * np.pi * eta * radii)[:, None, None]
    return m.transpose(0, 2, 1, 3).reshape(3 * n, 3 * n)


def power_fit(x, y, sigma=None):
    """Fit y = c x^p by weighted least squares in log-log; returns (p, dp, c)."""
    lx, ly = np.log(np.asarray(x, float)), np.log(np.asarray(y, float))
    w = None if sigma is None else 1.0 / (np.asarray(sigma, float) / np.asarray(y, float))
    coef, cov = np.polyfit(lx, ly, 1, w=w, cov="unscaled" if w is not None else True)
    return coef[0], float(np.sqrt(cov[0, 0])), float(np.exp(coef[1]))


def msd(x: np.ndarray, lags) -> tuple[np.ndarray, np.ndarray]:
    """Mean squared displacement of trajectories x (F, K, 3) (K walkers) at the
    given frame lags, averaged over all time origins and walkers; returns
    (msd, standard error) with the error from the spread over walkers and over
    non-overlapping blocks of length lag."""
    out, err = [], []
    for lag in lags:
        d2 = np.sum((x[lag:] - x[:-lag]) ** 2, axis=-1)  # (F-lag, K)
        out.append(d2.mean())
        blocks = d2[::lag]  # non-overlapping displacements: nearly independent
        err.append(blocks.std(ddof=1) / np.sqrt(blocks.size) if blocks.size > 1 else np.nan)
    return np.array(out), np.array(err)

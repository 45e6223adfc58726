"""Pure-Python helpers of the rpyfmm package: trajectory reading and the mean
squared displacement (MSD) used by the examples and tests. Their errors are
rpyfmm.Error subclasses, as those of the extension."""

from __future__ import annotations

import os
from typing import List, Tuple

import numpy as np
import numpy.typing as npt

from ._rpyfmm import FileError, InvalidArgumentError, InvalidInputError


def read_xyz(path: str | os.PathLike[str]) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reads an extended-XYZ trajectory written by the BD engine.

    Returns ``(times, steps, positions)`` with ``positions`` of shape
    (frames, N, 3) in length units (wrapped into the box for periodic runs, as
    written; 10 significant digits) and ``times`` in time units. A file that
    cannot be opened raises :class:`FileError`; one that is not such a
    trajectory (binary, truncated, malformed) :class:`InvalidInputError`; both
    name the file, as does a file with no frame or a path that is not a regular file
    (a directory, or a device such as /dev/zero, which would be read without end).
    """
    if os.path.exists(path) and not os.path.isfile(path):
        raise FileError(f"read_xyz: '{os.fspath(path)}' is not a regular file")
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except UnicodeDecodeError as e:
        raise InvalidInputError(f"read_xyz: '{os.fspath(path)}' is not a text file ({e})") from e
    except OSError as e:
        raise FileError(f"read_xyz: cannot read '{os.fspath(path)}': {e.strerror or e}") from e
    try:
        frames = _parse_xyz(text.splitlines())
    except (ValueError, IndexError) as e:
        raise InvalidInputError(f"read_xyz: '{os.fspath(path)}' is not an XYZ trajectory: {e}") from e
    if frames[2].size == 0:
        raise InvalidInputError(f"read_xyz: '{os.fspath(path)}' holds no frame")
    return frames


def _parse_xyz(lines: List[str]) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frames of an extended-XYZ text: (times, steps, positions); ValueError/IndexError when malformed."""
    times: List[float] = []
    steps: List[int] = []
    frames: List[np.ndarray] = []
    i = 0
    while i < len(lines):
        if not lines[i].strip():
            i += 1
            continue
        n = int(lines[i])
        header = lines[i + 1]
        fields = dict(tok.split("=", 1) for tok in header.split() if "=" in tok)
        times.append(float(fields.get("Time", "nan")))
        steps.append(int(fields.get("Step", "-1")))
        rows = [ln.split() for ln in lines[i + 2 : i + 2 + n]]
        if len(rows) != n:
            raise ValueError(f"frame {len(frames)} has {len(rows)} of its {n} atom lines")
        frames.append(np.array([[float(r[1]), float(r[2]), float(r[3])] for r in rows]))
        i += 2 + n
    return np.array(times), np.array(steps), np.array(frames)


def msd(positions: npt.ArrayLike) -> np.ndarray:
    """Mean squared displacement from the first frame.

    positions: (frames, N, 3) unwrapped positions (length units). Returns
    (frames,) values <|x_i(t) - x_i(0)|^2> averaged over particles
    (length^2 units). For free diffusion it grows as 6 D t.
    """
    x = np.asarray(positions, dtype=np.float64)
    if x.ndim != 3 or x.shape[2] != 3 or x.shape[0] == 0 or x.shape[1] == 0:
        raise InvalidInputError(f"msd: positions has shape {x.shape}, expected (frames, N, 3) with frames, N > 0")
    if not np.all(np.isfinite(x)):
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(x))[0])
        raise InvalidInputError(f"msd: positions entry {bad} is {'NaN' if np.isnan(x[bad]) else 'infinite'}")
    d = x - x[0]
    return np.mean(np.sum(d * d, axis=2), axis=1)


def stokes_einstein(kT: float, viscosity: float, radius: float) -> float:
    """Single-sphere diffusion coefficient D0 = kT / (6 pi eta a) (length^2 / time).

    kT must be finite and >= 0, viscosity and radius finite and > 0, none of them
    subnormal (nonzero but below 2.2e-308), as in the library (docs/safety-limits.md);
    otherwise, or where D0 overflows, :class:`InvalidArgumentError` names the argument.
    """
    for name, value, zero_ok in (("kT", kT, True), ("viscosity", viscosity, False), ("radius", radius, False)):
        v = float(value)
        if not (np.isfinite(v) and (v >= 0.0 if zero_ok else v > 0.0)):
            raise InvalidArgumentError(
                f"stokes_einstein: {name} must be finite and {'>= 0' if zero_ok else '> 0'}, got {value!r}")
        if v != 0.0 and abs(v) < np.finfo(np.float64).tiny:
            raise InvalidArgumentError(
                f"stokes_einstein: {name} must be a normal number (>= 2.2e-308), got the subnormal {value!r}")
    d0 = kT / (6.0 * np.pi * viscosity * radius)
    if not np.isfinite(d0):
        raise InvalidArgumentError(
            f"stokes_einstein: kT / (6 pi eta a) overflows for kT = {kT!r}, viscosity = {viscosity!r}, "
            f"radius = {radius!r}")
    return d0

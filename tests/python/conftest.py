"""Shared fixtures of the rpyfmm pytest suite.

The suite runs against the package in PYTHONPATH (ctest: <build>/python, or an
installed wheel); comparisons with the command-line tool use the binary named
by the RPYFMM_CLI environment variable (set by ctest) and skip without it.
"""

from __future__ import annotations

import os

# As the ctest presets do: idle OpenMP threads sleep instead of spinning (on a loaded
# 2-core machine spinning makes the suite ~5x slower). Read when libgomp loads, i.e.
# it must precede the first `import rpyfmm`.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import json
import subprocess
from pathlib import Path
from typing import Callable, List

import numpy as np
import pytest

import rpyfmm


@pytest.fixture(scope="session")
def cli() -> Callable[..., str]:
    """Runs `rpyfmm <args>`; returns stdout (fails the test on a non-zero exit)."""
    path = os.environ.get("RPYFMM_CLI", "")
    if not path or not Path(path).is_file():
        pytest.skip("RPYFMM_CLI does not name the rpyfmm binary")

    def run(*args: str, expect_rc: int = 0) -> str:
        proc = subprocess.run([path, *map(str, args)], capture_output=True, text=True, check=False)
        assert proc.returncode == expect_rc, proc.stderr
        return proc.stdout if expect_rc == 0 else proc.stderr

    return run


def cli_json(stdout: str) -> dict:
    """The last line of a `--json` run."""
    return json.loads(stdout.strip().splitlines()[-1])


def suspension(n: int, radius: float = 1.0, spacing: float = 2.4, seed: int = 0, jitter: float = 0.3) -> np.ndarray:
    """(n, 3) positions on a jittered cubic lattice (spacing in radii): a dilute suspension
    with a few close pairs, reproducible from `seed`."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(n ** (1.0 / 3.0)))
    grid = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    pick = rng.permutation(len(grid))[:n]
    x = grid[pick] * spacing * radius
    return x + rng.uniform(-jitter, jitter, size=x.shape) * radius


@pytest.fixture
def save_npy(tmp_path: Path) -> Callable[[str, np.ndarray], Path]:
    def save(name: str, array: np.ndarray) -> Path:
        path = tmp_path / name
        np.save(path, array)
        return path

    return save


def rel_err(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


__all__: List[str] = ["cli_json", "suspension", "rel_err", "rpyfmm"]

"""GSD trajectories (`[output] format = "gsd"`) read with the gsd package (gsd.hoomd), and with
MDAnalysis, freud and OVITO where they are installed: every frame against the run's own state (a
Simulation stepped alongside), the XYZ trajectory of the same run, and the run's log; restarts
equal to uninterrupted runs frame by frame; the example script examples/python/ecosystem.py."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rpyfmm

gsd_hoomd = pytest.importorskip("gsd.hoomd", reason="the gsd package (pip install gsd) reads GSD files")

ROOT = Path(__file__).resolve().parents[2]

# Two types, rotation, free space, free draining: every chunk the writer has.
OPEN = """
[system]
rotation = true
[[types]]
name = "A"
radius = 1.0
[[types]]
name = "Big"
radius = 1.5
dipole = 1.0
[particles]
source = "random"
count = 40
types = ["A", "Big"]
seed = 5
[external]
dipole_field = [0.0, 0.0, 2.0]
[integrator]
dt = 0.01
steps = 40
seed = 11
[mobility]
method = "none"
[output]
format = "{format}"
trajectory_every = 5
log_every = 5
checkpoint_every = 10
"""

# A periodic suspension with WCA repulsion: wrapped positions and images.
PERIODIC = """
[system]
geometry = "periodic"
box = [12.0, 12.0, 12.0]
[[types]]
name = "A"
[particles]
source = "random"
count = 60
seed = 2
[[pair]]
types = ["A", "A"]
kind = "wca"
[integrator]
dt = 0.05
steps = 60
[mobility]
method = "none"
[output]
format = "{format}"
trajectory_every = 10
log_every = 10
"""


def _require_gsd_support() -> None:
    try:
        rpyfmm.parse_config(OPEN.format(format="gsd"))
    except rpyfmm.Error as e:
        if "GSD support" in str(e):
            pytest.skip(f"this build of rpyfmm writes no GSD: {e}")
        raise


def _frames(path: Path) -> list:
    with gsd_hoomd.open(str(path), "r") as trajectory:
        return list(trajectory)


def _xyz_rows(path: Path) -> list:
    """Extended-XYZ frames as (comment line, rows split into fields)."""
    lines = path.read_text().splitlines()
    frames, i = [], 0
    while i < len(lines):
        n = int(lines[i])
        frames.append((lines[i + 1], [r.split() for r in lines[i + 2 : i + 2 + n]]))
        i += 2 + n
    return frames


@pytest.fixture(scope="module")
def open_runs(tmp_path_factory) -> Path:
    _require_gsd_support()
    base = tmp_path_factory.mktemp("gsd_open")
    for fmt in ("gsd", "xyz"):
        rpyfmm.run_bd(OPEN.format(format=fmt), out_dir=str(base / fmt))
    return base


def test_frames_hold_the_runs_positions_and_orientations(open_runs: Path):
    frames = _frames(open_runs / "gsd" / "trajectory.gsd")
    assert len(frames) == 9
    sim = rpyfmm.Simulation.from_config(OPEN.format(format="xyz"))
    for k, frame in enumerate(frames):
        if k:
            sim.run(5)
        assert frame.configuration.step == 5 * k == sim.step_count
        assert frame.log["bd/time"][0] == pytest.approx(sim.time, rel=1e-15)
        assert frame.particles.N == 40
        # float32 of the run's doubles, bit for bit; quaternions in HOOMD's (w, x, y, z) order
        np.testing.assert_array_equal(frame.particles.position, sim.positions.astype(np.float32))
        np.testing.assert_array_equal(frame.particles.orientation, sim.orientations.astype(np.float32))
        reach = np.abs(sim.positions) + (frame.particles.diameter / 2)[:, None]
        np.testing.assert_array_equal(frame.configuration.box[:3], (4 * reach.max(axis=0)).astype(np.float32))
        np.testing.assert_array_equal(frame.configuration.box[3:], 0)


def test_frames_match_the_xyz_trajectory_of_the_same_run(open_runs: Path):
    frames = _frames(open_runs / "gsd" / "trajectory.gsd")
    xyz = _xyz_rows(open_runs / "xyz" / "trajectory.xyz")
    assert len(frames) == len(xyz)
    for frame, (comment, rows) in zip(frames, xyz):
        assert f"Step={frame.configuration.step}" in comment
        assert frame.particles.types == ["A", "Big"]
        names = [frame.particles.types[t] for t in frame.particles.typeid]
        assert names == [r[0] for r in rows]
        np.testing.assert_array_equal(frame.particles.diameter, [2 * float(r[4]) for r in rows])
        pos = np.array([[float(v) for v in r[1:4]] for r in rows])
        np.testing.assert_allclose(frame.particles.position, pos, rtol=2e-7, atol=1e-12)  # float32 vs 10 digits
        q_xyzw = np.array([[float(v) for v in r[5:9]] for r in rows])
        np.testing.assert_allclose(frame.particles.orientation, q_xyzw[:, [3, 0, 1, 2]], rtol=0, atol=2e-7)


def test_restart_equals_the_uninterrupted_run_frame_by_frame(tmp_path: Path):
    _require_gsd_support()
    config = OPEN.format(format="gsd")
    rpyfmm.run_bd(config, out_dir=str(tmp_path / "whole"))
    rpyfmm.run_bd(config, steps=15, out_dir=str(tmp_path / "split"))
    assert len(_frames(tmp_path / "split" / "trajectory.gsd")) == 4
    rpyfmm.restart_bd(str(tmp_path / "split" / "checkpoint.bin"))
    whole, split = _frames(tmp_path / "whole" / "trajectory.gsd"), _frames(tmp_path / "split" / "trajectory.gsd")
    assert len(whole) == len(split) == 9
    for a, b in zip(whole, split):
        assert a.configuration.step == b.configuration.step
        for name in ("position", "orientation", "typeid", "diameter"):
            np.testing.assert_array_equal(getattr(a.particles, name), getattr(b.particles, name))
        np.testing.assert_array_equal(a.configuration.box, b.configuration.box)
        assert a.log["bd/time"] == b.log["bd/time"]


def test_periodic_frames_unwrap_to_the_logged_msd(tmp_path: Path):
    _require_gsd_support()
    rpyfmm.run_bd(PERIODIC.format(format="gsd"), out_dir=str(tmp_path / "gsd"))
    rpyfmm.run_bd(PERIODIC.format(format="xyz"), out_dir=str(tmp_path / "xyz"))
    frames = _frames(tmp_path / "gsd" / "trajectory.gsd")
    _, _, wrapped = rpyfmm.read_xyz(tmp_path / "xyz" / "trajectory.xyz")  # in [0, L)
    L = 12.0
    unwrapped = []
    for frame, xyz in zip(frames, wrapped):
        np.testing.assert_array_equal(frame.configuration.box, [L, L, L, 0, 0, 0])
        p = frame.particles.position.astype(np.float64)
        assert p.min() >= -L / 2 and p.max() < L / 2  # HOOMD's box is centred on the origin
        shift = (p - xyz) / L  # the same point up to whole box lengths
        np.testing.assert_allclose(shift, np.round(shift), rtol=0, atol=1e-5)
        unwrapped.append(p + frame.particles.image * L)
    log = np.genfromtxt(tmp_path / "gsd" / "log.csv", delimiter=",", names=True)
    msd = [np.mean(np.sum((x - unwrapped[0]) ** 2, axis=1)) for x in unwrapped]
    assert log["msd"][-1] > 0.1
    np.testing.assert_allclose(msd, log["msd"], rtol=1e-4, atol=1e-5)


def test_freud_reads_the_boxes(open_runs: Path, tmp_path: Path):
    freud = pytest.importorskip("freud")
    # Free space: the box is twice the spheres' extent, so freud's minimum-image pairs are the true ones.
    frame = _frames(open_runs / "gsd" / "trajectory.gsd")[-1]
    box = freud.box.Box.from_box(frame.configuration.box)
    points = frame.particles.position
    r_max = 6.0
    pairs = freud.locality.AABBQuery(box, points).query(points, {"r_max": r_max, "exclude_ii": True})
    found = {(int(i), int(j)) for i, j in pairs.toNeighborList()[:]}
    d = np.linalg.norm(points[:, None, :].astype(np.float64) - points[None, :, :], axis=2)
    expected = {(i, j) for i, j in zip(*np.nonzero(d < r_max)) if i != j}
    borderline = {(i, j) for i, j in zip(*np.nonzero(np.abs(d - r_max) < 1e-4))}  # float32 in freud
    assert found - borderline == expected - borderline


def test_mdanalysis_reads_every_frame(open_runs: Path):
    mda = pytest.importorskip("MDAnalysis")
    path = open_runs / "gsd" / "trajectory.gsd"
    universe = mda.Universe(str(path))
    frames = _frames(path)
    assert len(universe.trajectory) == len(frames)
    for ts, frame in zip(universe.trajectory, frames):
        np.testing.assert_allclose(ts.positions, frame.particles.position, rtol=0, atol=1e-5)


def test_ovito_reads_every_frame(open_runs: Path):
    # OVITO's GSD reader (the `ovito` package on PyPI): positions, types, radii (diameter / 2),
    # orientations (OVITO's (x, y, z, w) order), the box centred on the origin, the step and the
    # logged time of every frame, against the gsd package's reading of the same file.
    ovito_io = pytest.importorskip("ovito.io", reason="OVITO's Python module (pip install ovito)")
    path = open_runs / "gsd" / "trajectory.gsd"
    pipeline = ovito_io.import_file(str(path))
    frames = _frames(path)
    assert pipeline.num_frames == len(frames)
    for k, frame in enumerate(frames):
        data = pipeline.compute(k)
        particles = data.particles
        np.testing.assert_array_equal(np.asarray(particles.positions), frame.particles.position)
        np.testing.assert_array_equal(2 * np.asarray(particles["Radius"]), frame.particles.diameter)
        assert [t.name for t in particles.particle_types.types] == frame.particles.types
        np.testing.assert_array_equal(np.asarray(particles.particle_types), frame.particles.typeid)
        np.testing.assert_array_equal(np.asarray(particles["Orientation"]), frame.particles.orientation[:, [1, 2, 3, 0]])
        cell = np.asarray(data.cell[:, :])
        np.testing.assert_array_equal(np.diag(cell[:, :3]), frame.configuration.box[:3])
        np.testing.assert_array_equal(cell[:, 3], -frame.configuration.box[:3] / 2)
        assert data.attributes["Timestep"] == frame.configuration.step
        assert data.attributes["bd/time"] == frame.log["bd/time"][0]


def test_ecosystem_example_runs(tmp_path: Path):
    _require_gsd_support()
    script = ROOT / "examples" / "python" / "ecosystem.py"
    env = dict(os.environ, MPLBACKEND="Agg")
    args = [sys.executable, str(script), "--n", "150", "--steps", "60", "--out", str(tmp_path)]
    proc = subprocess.run(args, capture_output=True, text=True, env=env, check=False, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "frames read with gsd" in proc.stdout
    assert (tmp_path / "bd" / "trajectory.gsd").is_file()

"""Brownian dynamics of rigid bodies from Python (rpyfmm.RigidBodyDynamics): deterministic motion
against a dense NumPy body mobility, the random-finite-difference drift of an off-centre reference
point against its closed form -2 kT mu_r (q - c), a Python force function, reproducibility, and
errors."""

from __future__ import annotations

import numpy as np
import pytest

import rpyfmm


def rotation(q):
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def dense_body_mobility(x, radius, reference):
    """(K^T M^{-1} K)^{-1} of one body with beads x about `reference` (NumPy, dense)."""
    op = rpyfmm.DirectRpy()
    op.set_positions(x, radius)
    m = np.array(op.assemble_dense())
    k = np.zeros((3 * len(x), 6))
    for j, r in enumerate(x - reference):
        k[3 * j:3 * j + 3, :3] = np.eye(3)
        k[3 * j:3 * j + 3, 3:] = -np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
    return np.linalg.inv(k.T @ np.linalg.solve(m, k))


def test_deterministic_motion_and_force_function():
    shape = 1.5 * rpyfmm.icosphere_beads(1)
    a = 1.5 * rpyfmm.icosphere_bead_radius(1)
    q0 = np.array([[0.5, 0.0, -1.0]])
    w = np.array([0.2, -0.1, 0.3, 0.05, 0.1, -0.2])
    calls = []

    def forces(t, positions, orientations, beads):
        calls.append((t, positions.shape, orientations.shape, beads.shape))
        return w.reshape(1, 6)

    sim = rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), shape, a, [0, 42], q0, dt=0.1, kT=0.0, tolerance=1e-11,
                                   forces=forces)
    sim.run(10)
    assert calls[0] == (0.0, (1, 3), (1, 4), (42, 3)) and len(calls) == 10
    y = dense_body_mobility(shape + q0, a, q0[0]) @ w
    np.testing.assert_allclose(sim.positions[0], q0[0] + 1.0 * y[:3], atol=1e-9)
    omega = y[3:]
    angle = np.linalg.norm(omega)
    axis = omega / angle
    expected = np.array([np.cos(angle / 2), *(np.sin(angle / 2) * axis)])  # turned by |omega| t, t = 1
    q = sim.orientations[0]
    np.testing.assert_allclose(q * np.sign(q[0]), expected, atol=1e-9)
    np.testing.assert_allclose(sim.bead_positions, shape @ rotation(q).T + sim.positions[0], atol=1e-12)
    assert sim.step_count == 10 and sim.time == pytest.approx(1.0)
    assert sim.totals["drift_iterations"] == 0 and sim.totals["solve_iterations"] > 0


def test_drift_of_an_off_centre_reference_point():
    d = np.array([0.6, 0.2, -0.3])
    shape = 1.5 * rpyfmm.icosphere_beads(0) - d
    q0 = np.array([[1.0, 2.0, -0.5]])
    quat = np.array([[0.3, -0.5, 0.2, 0.7]])
    sim = rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), shape, 0.7, [0, 12], q0, quat, dt=0.01, tolerance=1e-10)
    divergence = sum(sim.drift_estimate(np.eye(6)[k])[0] for k in range(6))
    arm = rotation(quat[0]) @ d
    beads = sim.bead_positions
    mu_r = dense_body_mobility(beads, 0.7, q0[0] - arm)[3, 3]
    np.testing.assert_allclose(divergence[:3], -2.0 * mu_r * arm, rtol=1e-5)
    assert np.linalg.norm(divergence[3:]) < 1e-5 * mu_r


def test_reproducible_brownian_steps_and_report():
    shape = rpyfmm.icosphere_beads(0)
    x = np.vstack([shape + [0.3, 0, 0], shape])
    args = (x, 0.5, [0, 12, 24], [[0, 0, 0], [3, 0.5, 0]])
    one = rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), *args, dt=0.01, seed=4)
    two = rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), *args, dt=0.01, seed=4)
    r = one.run(3)
    two.run(3)
    np.testing.assert_array_equal(one.positions, two.positions)
    np.testing.assert_array_equal(one.orientations, two.orientations)
    assert r.drift_iterations > 0 and r.sqrt_iterations > 0 and "RigidStepReport" in repr(r)
    assert set(one.totals["seconds"]) >= {"plan", "sqrt", "solve", "drift", "update"}
    assert one.last_drift.shape == (2, 6) and np.all(np.isfinite(one.last_drift))
    np.testing.assert_allclose(np.linalg.norm(one.orientations, axis=1), 1.0, atol=1e-14)
    w = one.bead_forces_to_bodies(np.tile([0.0, 0.0, 1.0], (24, 1)))
    np.testing.assert_allclose(w[:, 2], [12.0, 12.0])


def test_errors():
    shape = rpyfmm.icosphere_beads(0)
    op = rpyfmm.DirectRpy()
    with pytest.raises(rpyfmm.InvalidArgumentError, match="dt"):
        rpyfmm.RigidBodyDynamics(op, shape, 0.5, [0, 12], [[0, 0, 0]], dt=0.0)
    with pytest.raises(rpyfmm.InvalidArgumentError, match="drift"):
        rpyfmm.RigidBodyDynamics(op, shape, 0.5, [0, 12], [[0, 0, 0]], dt=0.1, drift="fixman")
    with pytest.raises(rpyfmm.InvalidInputError, match="orientations"):
        rpyfmm.RigidBodyDynamics(op, shape, 0.5, [0, 12], [[0, 0, 0]], [[1, 0, 0]], dt=0.1)
    with pytest.raises(rpyfmm.InvalidInputError, match="zero quaternion"):
        rpyfmm.RigidBodyDynamics(op, shape, 0.5, [0, 12], [[0, 0, 0]], [[0, 0, 0, 0]], dt=0.1)
    with pytest.raises(rpyfmm.InvalidArgumentError, match="callable"):
        rpyfmm.RigidBodyDynamics(op, shape, 0.5, [0, 12], [[0, 0, 0]], dt=0.1, forces=3)
    bad = rpyfmm.RigidBodyDynamics(op, shape, 0.5, [0, 12], [[0, 0, 0]], dt=0.1,
                                   forces=lambda t, q, o, b: np.zeros(5))
    with pytest.raises(rpyfmm.InvalidInputError, match="shape"):
        bad.step()

    def failing(t, q, o, b):
        raise RuntimeError("force field broke")

    broken = rpyfmm.RigidBodyDynamics(op, shape, 0.5, [0, 12], [[0, 0, 0]], dt=0.1, forces=failing)
    with pytest.raises(RuntimeError, match="force field broke"):
        broken.step()
    assert broken.step_count == 0
    nan = rpyfmm.RigidBodyDynamics(op, shape, 0.5, [0, 12], [[0, 0, 0]], dt=0.1,
                                   forces=lambda t, q, o, b: np.full((1, 6), np.nan))
    with pytest.raises(rpyfmm.InvalidInputError, match="non-finite"):
        nan.step()


def test_pair_repulsion_between_bodies():
    shape = rpyfmm.icosphere_beads(0)
    x = np.vstack([shape, shape])
    sim = rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), x, 0.5, [0, 12, 24], [[0, 0, 0], [2.0, 0.2, 0]], dt=0.01,
                                   kT=0.0, pair={"kind": "soft", "epsilon": 5.0, "sigma": 1.0})
    r = sim.step()
    w = sim.last_forces_torques
    assert r.potential_energy > 0 and w[1, 0] > 0 > w[0, 0]
    np.testing.assert_allclose(w[0, :3], -w[1, :3], atol=1e-12)  # action = reaction
    sim.run(20)
    assert sim.positions[1, 0] - sim.positions[0, 0] > 2.0
    # A hard potential between the beads of one body is not evaluated (its beads are 1.05 apart).
    apart = rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), x, 0.5, [0, 12, 24], [[0, 0, 0], [9.0, 0, 0]], dt=0.01,
                                     pair={"kind": "wca", "sigma": 1.5})
    assert apart.run(2).potential_energy == 0.0
    with pytest.raises(rpyfmm.InvalidArgumentError, match="unknown pair key"):
        rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), x, 0.5, [0, 12, 24], [[0, 0, 0], [9.0, 0, 0]], dt=0.01,
                                 pair={"range": 2})


def test_restart_with_first_step_continues_bit_for_bit():
    shape = rpyfmm.icosphere_beads(0)
    x = np.vstack([shape + [0.3, 0, 0], shape])
    q0 = [[0, 0, 0], [3, 0.5, 0]]

    def make(positions, orientations=None, first_step=0):
        return rpyfmm.RigidBodyDynamics(rpyfmm.DirectRpy(), x, 0.5, [0, 12, 24], positions, orientations, dt=0.01,
                                        seed=11, first_step=first_step)

    full = make(q0)
    full.run(10)
    first = make(q0)
    first.run(6)
    second = make(first.positions, first.orientations, first_step=first.step_count)
    second.run(4)
    assert second.step_count == 10 and second.time == pytest.approx(0.1)
    np.testing.assert_array_equal(second.positions, full.positions)
    np.testing.assert_array_equal(second.orientations, full.orientations)

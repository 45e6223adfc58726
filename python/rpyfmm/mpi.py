"""rpyfmm.mpi — the MPI layer's distributed operators from Python via mpi4py.

Available where the module was built with the MPI layer (CMake option ``RPYFMM_USE_MPI``,
on by default where MPI and FFTW-MPI are found) and mpi4py, built against the same MPI, is
installed (Debian: ``python3-mpi4py``). Importing this module imports ``mpi4py.MPI``, which
initializes MPI. docs/mpi.md, "Python (mpi4py)", lists what is supported.

* :class:`DistributedDirectRpy` (exact, free space), :class:`DistributedFmmRpy` (FMM, free
  space) and :class:`DistributedPseRpy` (PSE, periodic): ``set_positions`` / ``apply`` /
  ``apply_sqrt`` with this rank's share of the particles as (n, 3) or (3n,) NumPy arrays
  (n may be 0); the global particle order is the ranks' shares concatenated in rank order.
* All three also have the grand mobility with rotation, ``apply(forces, torques)`` returning
  ``(U, W)`` as :meth:`rpyfmm.DirectRpy.apply` does (``supports_rotation``).
* :class:`DistributedDirectRpy` and :class:`DistributedFmmRpy` also sample several right-hand
  sides in one call, ``apply_sqrt_block(z)`` with z of shape (nrhs, n, 3) or (nrhs, 3n), as
  :meth:`rpyfmm.DirectRpy.apply_sqrt_block`; each column equals ``apply_sqrt`` of it alone bit for bit.
* :class:`DistributedRigidBodies` ``(beads, tolerance=..., ...)``: :class:`rpyfmm.RigidBodies`
  with whole bodies per rank and the bead products across the ranks (``beads`` a
  :class:`DistributedDirectRpy`, :class:`DistributedFmmRpy` or, in a periodic box with equal radii,
  :class:`DistributedPseRpy`, kept alive); ``set_configuration``,
  ``apply``, ``apply_with_bead_forces``, ``apply_from`` (GMRES from this rank's guesses),
  ``apply_with_noise``, ``mobility_matrix`` with this rank's bodies and beads.
* :class:`RigidBodyDynamics` ``(beads, shape, radius, body_offsets, positions, orientations=None, *,
  dt, kT, seed, ..., forces=None, pair=None)``: :class:`rpyfmm.RigidBodyDynamics` with whole bodies
  per rank (``beads`` a :class:`DistributedDirectRpy`, :class:`DistributedFmmRpy` or
  :class:`DistributedPseRpy`, kept alive; ``pair`` the serial class's bead pair potential between
  bodies on all ranks): ``step`` / ``run``, this rank's ``positions``, ``orientations``, ``bead_positions``,
  ``lever_arms`` (copies), ``last_report``, ``totals``; ``forces`` is called on every rank with its
  own bodies' state, and an exception in it raises :class:`rpyfmm.InvalidInputError` on every rank.
  With :class:`DistributedDirectRpy` and ``preconditioner="none"`` the trajectory is
  :class:`rpyfmm.RigidBodyDynamics`'s with :class:`rpyfmm.DirectRpy` to round-off (bit for bit on
  one rank); with :class:`DistributedPseRpy` (its periodic box, nothing wrapped, its split
  sampler) that with :class:`rpyfmm.PseRpy` (``wave_precision="double"``) to round-off.
* Statistics of this rank (copies; reading them is not collective): ``inner_products`` of the last
  sampler call and ``counts`` on :class:`DistributedDirectRpy` and :class:`DistributedFmmRpy`,
  ``communication`` (dicts of the C++ classes' ``communication()``) on those and
  :class:`DistributedLaplaceFmm`, ``exchange_counts`` on :class:`DistributedPseRpy`.
* :class:`DistributedPseRpy` also has the split sampler ``sample(seed, step)`` and
  ``apply_with_noise``.
* :class:`DistributedLaplaceFmm`: ``set_points`` / ``evaluate`` with this rank's sources (and
  targets, and partition weights) and charges, the layouts of :class:`rpyfmm.LaplaceFmm`;
  ``measured_weights`` of the last evaluation balance the next plan by the work.
* :func:`normal_noise` ``(n, offset, seed, step=0, stream=0)``: this rank's rows of
  :func:`rpyfmm.normal_noise` (not collective).
* :func:`run_bd` ``(comm, config, steps=None, out_dir=None, progress=False)`` and
  :func:`restart_bd` ``(comm, checkpoint, ...)``: whole Brownian dynamics runs across the ranks,
  as ``mpirun rpyfmm bd`` (``DistributedBd``; rank 0 writes the files; the summary has
  ``"ranks"``).
* :class:`Simulation` ``(comm, config)``: the same runs step by step (``step`` / ``run``), each rank
  holding its share of the particles (``positions``, ``ids``, ``types``, ``last_forces``, ...;
  copies; reading them is not collective), ``gather()`` the whole state on one rank; with free
  draining the positions are :meth:`rpyfmm.Simulation.from_config`'s bit for bit.
* :class:`SfcPartition` ``(comm, positions, weights=None, curve="morton")``: the Morton- or
  Hilbert-curve partition of the particles the ranks hold (``owned_indices``, ``owned_counts``, ``splitters``, ...) and
  ``to_owners`` / ``to_origin`` moving per-particle rows to the owners and back.

Constructors take an mpi4py communicator (``MPI.COMM_WORLD`` or any intra-communicator) and
keep a reference to it (the object's ``comm``). Every method is collective: all ranks of the
communicator call it in the same order. A bad argument or input on any rank raises the same
:class:`rpyfmm.Error` subclass with the same message (naming the first failing rank) on every
rank.

Example (run with ``mpirun -n 2 python script.py``)::

    from mpi4py import MPI
    import numpy as np
    import rpyfmm.mpi

    comm = MPI.COMM_WORLD
    op = rpyfmm.mpi.DistributedFmmRpy(comm, viscosity=1.0, tolerance=1e-6)
    x = np.random.default_rng(comm.rank).uniform(0, 50, (1000, 3))  # this rank's particles
    op.set_positions(x, 1.0)
    u = op.apply(np.ones_like(x))  # velocities of this rank's particles
"""

from __future__ import annotations

from . import _rpyfmm

if not hasattr(_rpyfmm, "mpi"):
    raise ImportError(
        "rpyfmm.mpi: this rpyfmm module was built without MPI. Rebuild it with the MPI layer: "
        "install an MPI and FFTW-MPI development environment (Debian: libopenmpi-dev openmpi-bin "
        "libfftw3-mpi-dev), then configure with -DRPYFMM_USE_MPI=ON -DRPYFMM_BUILD_PYTHON=ON "
        "(or `pip install .`, which turns MPI on where it finds both); docs/mpi.md"
    )

try:
    from mpi4py import MPI  # noqa: F401  (initializes MPI before any operator is made)
except ImportError as e:
    raise ImportError(
        "rpyfmm.mpi needs mpi4py, built against the MPI rpyfmm was built with "
        "(Debian: apt-get install python3-mpi4py)"
    ) from e

DistributedDirectRpy = _rpyfmm.mpi.DistributedDirectRpy
DistributedFmmRpy = _rpyfmm.mpi.DistributedFmmRpy
DistributedPseRpy = _rpyfmm.mpi.DistributedPseRpy
DistributedLaplaceFmm = _rpyfmm.mpi.DistributedLaplaceFmm
normal_noise = _rpyfmm.mpi.normal_noise
run_bd = _rpyfmm.mpi.run_bd
restart_bd = _rpyfmm.mpi.restart_bd
Simulation = _rpyfmm.mpi.Simulation
SfcPartition = _rpyfmm.mpi.SfcPartition
DistributedRigidBodies = _rpyfmm.mpi.DistributedRigidBodies
RigidBodyDynamics = _rpyfmm.mpi.RigidBodyDynamics

__all__ = [
    "DistributedDirectRpy",
    "DistributedFmmRpy",
    "DistributedLaplaceFmm",
    "DistributedPseRpy",
    "DistributedRigidBodies",
    "RigidBodyDynamics",
    "SfcPartition",
    "Simulation",
    "normal_noise",
    "restart_bd",
    "run_bd",
]

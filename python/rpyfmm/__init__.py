"""rpyfmm — fast Rotne-Prager-Yamakawa hydrodynamics from NumPy.

The Laplace FMM (:class:`LaplaceFmm`, :func:`laplace_direct`), the RPY mobility
operators behind one interface (:class:`DirectRpy`, :class:`FmmRpy`,
:class:`PseRpy`, :class:`OpenPseRpy`, :class:`FreeDraining`, :func:`make_mobility`; on a GPU
:class:`PseRpyCuda`, which takes CuPy/PyTorch device arrays through DLPack, :mod:`rpyfmm.cuda`), the Brownian
samplers (``apply_sqrt``, :func:`sqrt_apply`, :func:`normal_noise`,
:class:`SqrtReport`), rigid bodies of beads (:class:`RigidBodies`,
:func:`icosphere_beads`, and their Brownian dynamics :class:`RigidBodyDynamics`) and
Brownian dynamics of beads (:func:`run_bd`,
:class:`Simulation` with Python force callbacks).

Drop-in modules for users of other libraries (docs/ecosystem.md):
:mod:`rpyfmm.fmm3d` (fmm3dpy's ``lfmm3d``) and :mod:`rpyfmm.libmobility`
(libMobility's ``NBody``, ``PSE``, ``SelfMobility``).

Arrays: positions/forces/velocities are (N, 3) or (3N,), results come back in
the input's shape as float64. A float64 C-contiguous array is used in place
(no copy); float32, integer or strided inputs are converted once (a copy).
``out=`` arrays are written in place and returned. Units are the caller's:
with viscosity eta and radius a the self mobility is 1/(6 pi eta a).
Arrays handed to Python callbacks (Simulation forces, sqrt_apply's matvec,
RigidBodyDynamics forces) own their memory: a callback may keep them.

Errors raise :class:`Error` subclasses (RuntimeError; argument errors are also
ValueError) whose message is the C++ library's, naming the bad argument; standard
C++ exceptions map onto the same classes. The GIL is released during
computations; calls on one object from several Python threads are serialized
(docs/safety-python.md). :func:`set_num_threads` sets the OpenMP thread count
(1 to 4 x the hardware threads, at most 1024).

Constants:

* ``POTENTIAL``, ``GRADIENT``, ``HESSIAN``: bits of the ``outputs`` mask of
  :meth:`LaplaceFmm.evaluate` and :func:`laplace_direct`; ``ALL_OUTPUTS`` is
  all three.
* ``RESULT_COLUMNS``: names of the 10 result columns (pot, gx, gy, gz, hxx,
  hyy, hzz, hxy, hxz, hyz).
* ``__version__``: the library version.
"""

from __future__ import annotations

from ._rpyfmm import (
    ALL_OUTPUTS,
    GRADIENT,
    HESSIAN,
    POTENTIAL,
    RESULT_COLUMNS,
    DirectRpy,
    Error,
    FileError,
    FmmRpy,
    FreeDraining,
    InvalidArgumentError,
    InvalidInputError,
    LaplaceFmm,
    MobilityOperator,
    NotSupportedError,
    NumericalFailureError,
    OutOfMemoryError,
    OpenPseRpy,
    PseRpy,
    PseRpyCuda,
    RigidBodies,
    RigidBodyDynamics,
    RigidBodyReport,
    RigidStepReport,
    RunConfig,
    Simulation,
    SpectrumBounds,
    SqrtReport,
    StepReport,
    __version__,
    cuda_device_available,
    default_fmm_crossover,
    demo_config_text,
    estimate_spectrum_bounds,
    fit_leaf_grid,
    fmm_default_leaf_capacity,
    get_num_threads,
    icosphere_bead_radius,
    icosphere_beads,
    laplace_direct,
    load_config,
    make_mobility,
    normal_noise,
    parse_config,
    restart_bd,
    run_bd,
    set_num_threads,
    simd_level,
    sqrt_apply,
)
from . import cuda
from ._helpers import msd, read_xyz, stokes_einstein

__all__ = [
    "ALL_OUTPUTS",
    "GRADIENT",
    "HESSIAN",
    "POTENTIAL",
    "RESULT_COLUMNS",
    "DirectRpy",
    "Error",
    "FileError",
    "FmmRpy",
    "FreeDraining",
    "InvalidArgumentError",
    "InvalidInputError",
    "LaplaceFmm",
    "MobilityOperator",
    "NotSupportedError",
    "NumericalFailureError",
    "OutOfMemoryError",
    "OpenPseRpy",
    "PseRpy",
    "PseRpyCuda",
    "RigidBodies",
    "RigidBodyDynamics",
    "RigidBodyReport",
    "RigidStepReport",
    "RunConfig",
    "Simulation",
    "SpectrumBounds",
    "SqrtReport",
    "StepReport",
    "__version__",
    "cuda",
    "cuda_device_available",
    "default_fmm_crossover",
    "demo_config_text",
    "estimate_spectrum_bounds",
    "fit_leaf_grid",
    "fmm_default_leaf_capacity",
    "get_num_threads",
    "icosphere_bead_radius",
    "icosphere_beads",
    "laplace_direct",
    "load_config",
    "make_mobility",
    "msd",
    "normal_noise",
    "parse_config",
    "read_xyz",
    "restart_bd",
    "run_bd",
    "set_num_threads",
    "simd_level",
    "sqrt_apply",
    "stokes_einstein",
]

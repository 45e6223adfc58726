"""libMobility-compatible solvers: ``from rpyfmm.libmobility import NBody, PSE, SelfMobility``.

Solver classes with the names and semantics of libMobility's Python interface
(stochasticHydroTools/libMobility, version 1.x), computed by rpyfmm's operators,
so that code written for libMobility runs by changing the import:

================  =========================  ===========================================
libMobility       periodicity (X, Y, Z)      rpyfmm operator
================  =========================  ===========================================
``NBody``         open, open, open           ``make_mobility("auto")``: DirectRpy below
                                             the FMM crossover, FmmRpy above; or chosen by
                                             ``setParameters(algorithm="direct"|"fmm")``
``PSE``           periodic x 3               ``PseRpy`` (box Lx, Ly, Lz; psi -> xi),
                                             with torques too; ``PseRpyCuda`` with
                                             ``setParameters(..., device="cuda")``
``SelfMobility``  open, open, open           ``FreeDraining`` (1/(6 pi eta a), rotation
                                             1/(8 pi eta a^3))
``DPStokes``      --                         refused (NotSupportedError)
================  =========================  ===========================================

The interface (libMobility 1.x)::

    solver = NBody("open", "open", "open")
    solver.setParameters()                                  # solver-specific, before initialize
    solver.initialize(viscosity=1.0, hydrodynamicRadius=1.0, includeAngular=False,
                      tolerance=1e-4, seed=None)
    solver.setPositions(x)                                  # (N, 3) or (3N,)
    U, W = solver.Mdot(forces=F, torques=None)             # W is None without includeAngular
    dU, dW = solver.sqrtMdotW(prefactor=1.0)               # prefactor * M^{1/2} xi, xi ~ N(0, 1)
    V, Om = solver.LangevinVelocities(dt, kbt, forces=F)   # M F + sqrt(2 kbt / dt) M^{1/2} xi + kbt div M
    dU, dW = solver.divM(prefactor=1.0)                    # prefactor * div M (zero here)
    solver.clean()

Results are float64 (``precision == "double"``) in the shape of the forces (or of
the torques, or of the positions when neither is given), as libMobility returns
them; a flat (3N,) input gives flat results.

The earlier spelling (libMobility before 0.9) is accepted too, chosen by passing
``temperature`` to initialize by keyword::

    solver.initialize(temperature=kT, viscosity=1.0, hydrodynamicRadius=1.0,
                      needsTorque=False, numberParticles=None, tolerance=1e-4)
    solver.sqrtMdotW(prefactor)                   # prefactor * sqrt(2 kT M) xi
    solver.hydrodynamicVelocities(F, T, prefactor)  # M F + prefactor * sqrt(2 kT M) xi
    solver.thermalDrift(prefactor)               # prefactor * kT div M (zero here)

What differs from libMobility:

* Unsupported geometries and options are refused by name with
  :class:`rpyfmm.NotSupportedError` (a NotImplementedError): single_wall and
  two_walls periodicities (NBody's wall, DPStokes), PSE's shearStrain,
  NBody batches (Nbatch > 1), lanczos_callback.
* PSE accepts torques (includeAngular=True: PseRpy's grand mobility with
  rotation), where libMobility's PSE refuses them.
* The noise: xi is rpyfmm's counter-based normal stream (Philox), keyed by the
  seed and a call counter (translations stream 0, rotations stream 3), not
  libMobility's generator: the same distribution, different numbers. seed = None
  or 0 draws a random seed, as libMobility does. ``M^{1/2}`` is a square root of
  the mobility by Lanczos (PSE: the split sampler; SelfMobility: exact) to
  ``tolerance``; with includeAngular, (dU, dW) = B xi with B B^T the grand
  mobility (rpyfmm's ``apply_sqrt_rotation``).
* The divergence of the mobility is zero for every solver here (RPY with one
  radius in free space and in a periodic box), so divM returns zeros and
  LangevinVelocities adds nothing for it.
* Accuracy: ``tolerance`` is also the requested relative error of the FMM and
  PSE products (clamped to the operators' ranges: FMM [1e-12, 1e-1], PSE
  [1e-8, 0.1)); libMobility's NBody is exact, and so is rpyfmm's DirectRpy.
* Device arrays: ``PSE`` with ``setParameters(..., device="cuda")`` (the operator
  :class:`rpyfmm.PseRpyCuda`) takes CuPy arrays and PyTorch tensors on the GPU (float64,
  C-contiguous, the current device) in setPositions, Mdot, sqrtMdotW, LangevinVelocities,
  hydrodynamicVelocities and divM, read and written in place, and returns arrays of the input's
  framework (of the positions' where the call has no array argument); host arrays work as
  before. The first setPositions, and one that changes N, builds the operator's plan from a
  host copy of the positions; later ones move the particles on the device. Its noise is
  PseRpyCuda.sample's (PSE's split sampler keyed by (seed, call)) for host and device arrays
  alike, so both give the same numbers; with includeAngular=True device arrays are taken by
  Mdot only (the rotational square root has no device entry point). Every other solver takes
  host arrays only and raises :class:`rpyfmm.InvalidInputError` naming a device array
  (docs/python.md, "Device arrays").
* Host arrays of another framework than NumPy (a PyTorch CPU tensor) are read as
  NumPy reads them, and the results come back in that framework, without a copy
  (of the positions' where the call has no array argument), as libMobility
  returns its results; NumPy arrays and lists give NumPy arrays.
* Inputs are checked: wrong sizes, non-finite values, calls out of order and
  unknown periodicity names raise :class:`rpyfmm.InvalidArgumentError` or
  :class:`rpyfmm.InvalidInputError` (both ValueError) naming the problem.
"""

from __future__ import annotations

import math
import numbers
import secrets
import sys
from typing import Any, Dict, Optional, Tuple

import numpy as np
import numpy.typing as npt

from ._rpyfmm import (
    FreeDraining,
    InvalidArgumentError,
    InvalidInputError,
    MobilityOperator,
    NotSupportedError,
    PseRpy,
    PseRpyCuda,
    cuda,
    make_mobility,
    normal_noise,
)

__all__ = ["DPStokes", "NBody", "PSE", "SelfMobility"]

_PERIODICITIES = ("open", "unspecified", "single_wall", "two_walls", "periodic")
_ROTATION_STREAM = 3  # rpyfmm BD's stream of rotational noise (docs/python.md)

ArrayOrNone = Optional[np.ndarray]
# What the public methods return: (U, W), W None without includeAngular. NumPy arrays for NumPy or
# list input; otherwise arrays of the input's own framework (a PyTorch CPU tensor, a CuPy or PyTorch
# device array: docs/python.md, "Drop-ins for fmm3dpy and libMobility"), hence Any.
Velocities = Tuple[Any, Optional[Any]]


def _real(value: object, name: str, where: str, minimum: Optional[float] = None, strict: bool = True) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise InvalidArgumentError(f"{where}: {name} must be a finite number (got {value!r})")
    v = float(value)
    if minimum is not None and (v <= minimum if strict else v < minimum):
        raise InvalidArgumentError(f"{where}: {name} must be {'>' if strict else '>='} {minimum:g} (got {v:g})")
    return v


def _dlpack_device(value: object) -> Optional[Tuple[int, int]]:
    """The DLPack device of a device array; None for host arrays (kDLCPU = 1) and non-arrays."""
    device = getattr(value, "__dlpack_device__", None)
    if device is None or isinstance(value, np.ndarray):
        return None
    try:
        d = tuple(int(v) for v in device())
    except Exception:  # not a DLPack device: the array's own reading reports the problem (as in C++)
        return None
    return None if len(d) != 2 or d[0] == 1 else (d[0], d[1])


def _host_framework(value: object) -> Optional[Any]:
    """from_dlpack of the framework of a host array other than NumPy's (a PyTorch CPU tensor, ...),
    which wraps a NumPy result without a copy; None for NumPy arrays, lists and device arrays.
    libMobility returns its results in the input's framework on the host too."""
    if value is None or isinstance(value, np.ndarray) or getattr(value, "__dlpack_device__", None) is None:
        return None
    if _dlpack_device(value) is not None:
        return None
    module = sys.modules.get(type(value).__module__.split(".")[0])
    return getattr(module, "from_dlpack", None) if module is not None and module is not np else None


def _flat3(value: object, name: str, where: str) -> Tuple[np.ndarray, Tuple[int, ...]]:
    """A real (N, 3) or (3N,) array -> (float64 (N, 3) C-contiguous, original shape)."""
    device = _dlpack_device(value)
    if device is not None:
        raise InvalidInputError(
            f"{where}: {name} is a device array (DLPack device {device}); this solver takes host "
            "arrays: copy it to the host (cupy.asnumpy(x), x.cpu().numpy()), or use PSE with "
            "setParameters(..., device='cuda') or rpyfmm.PseRpyCuda, which read CUDA arrays in place"
        )
    a = np.asarray(value)
    if a.dtype.kind not in "biuf":
        raise InvalidArgumentError(f"{where}: {name} must be a real array (got dtype {a.dtype})")
    if not ((a.ndim == 1 and a.size % 3 == 0 and a.size > 0) or (a.ndim == 2 and a.shape[1] == 3 and a.shape[0] > 0)):
        raise InvalidInputError(f"{where}: {name} has shape {a.shape}, expected (N, 3) or (3N,) with N >= 1")
    x = np.ascontiguousarray(a, dtype=np.float64).reshape(-1, 3)
    if not np.isfinite(x).all():
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
        raise InvalidInputError(f"{where}: {name} entry {bad} is {a[bad]} (values must be finite)")
    return x, a.shape


def _array_module(value: object, name: str, where: str) -> Any:
    """cupy or torch, the framework of a device argument (its zeros_like and arithmetic make the
    results of the CUDA solver)."""
    module = sys.modules.get(type(value).__module__.split(".")[0])
    if module is None or module.__name__ not in ("cupy", "torch"):
        raise InvalidInputError(
            f"{where}: {name} is a device array of type {type(value).__module__}.{type(value).__name__}; "
            "rpyfmm.libmobility's CUDA solver takes CuPy arrays and PyTorch tensors")
    return module


class _Solver:
    """Common libMobility interface; subclasses build the rpyfmm operator."""

    precision = "double"
    _geometry: Tuple[str, str, str] = ("open", "open", "open")
    # True where the operator reads CUDA device arrays in place (PSE with device="cuda").
    _device_arrays = False

    def __init__(self, periodicityX: str, periodicityY: str, periodicityZ: str) -> None:
        name = type(self).__name__
        given = (periodicityX, periodicityY, periodicityZ)
        for axis, p in zip("XYZ", given):
            if not isinstance(p, str) or p not in _PERIODICITIES:
                raise InvalidArgumentError(
                    f"{name}: periodicity{axis} = {p!r} is not a libMobility periodicity "
                    f"(expected one of {', '.join(_PERIODICITIES)})")
        if given != self._geometry:
            raise NotSupportedError(
                f"{name}: periodicity ({', '.join(given)}) is not supported by rpyfmm; {name} takes "
                f"({', '.join(self._geometry)}){self._geometry_note(given)}")
        self._params: Dict[str, Any] = self._default_parameters()
        self._parameters_set = False
        self._op: Optional[MobilityOperator] = None
        self._initialized = False
        self._n = 0
        self._shape: Tuple[int, ...] = ()
        self._like: Any = None  # the device positions of the last setPositions (None: host)

    # -- solver-specific hooks ---------------------------------------------------------------
    def _geometry_note(self, given: Tuple[str, str, str]) -> str:
        return ""

    def _default_parameters(self) -> Dict[str, Any]:
        return {}

    def _make_operator(self, viscosity: float, tolerance: float) -> MobilityOperator:
        raise NotImplementedError

    # -- the interface -----------------------------------------------------------------------
    def initialize(
        self,
        viscosity: float,
        hydrodynamicRadius: float,
        includeAngular: bool = False,
        tolerance: float = 1e-4,
        seed: Optional[int] = None,
        lanczos_callback: Any = None,
        *,
        temperature: Optional[float] = None,
        needsTorque: Optional[bool] = None,
        numberParticles: Optional[int] = None,
    ) -> None:
        """Sets the fluid and particle parameters and builds the operator (after setParameters).

        viscosity: eta > 0; hydrodynamicRadius: a > 0 (one radius for all particles);
        includeAngular: torques in and angular velocities out; tolerance: relative accuracy of
        the square root (and of the FMM / PSE products), in (0, 1); seed: noise seed (None or 0:
        random). lanczos_callback: not supported. temperature, needsTorque, numberParticles: the
        spelling of libMobility before 0.9 (keywords only; temperature selects its sqrtMdotW and
        hydrodynamicVelocities conventions, see the module docstring).
        """
        where = f"{type(self).__name__}.initialize"
        if not isinstance(includeAngular, (bool, np.bool_)):
            raise InvalidArgumentError(
                f"{where}: includeAngular must be True or False (got {includeAngular!r}); "
                "the spelling initialize(temperature, viscosity, hydrodynamicRadius, ...) of libMobility "
                "before 0.9 is accepted with keywords: initialize(temperature=..., viscosity=..., "
                "hydrodynamicRadius=...)")
        if needsTorque is not None:
            if not isinstance(needsTorque, (bool, np.bool_)):
                raise InvalidArgumentError(f"{where}: needsTorque must be True or False (got {needsTorque!r})")
            if includeAngular and not needsTorque:
                raise InvalidArgumentError(f"{where}: includeAngular=True and needsTorque=False disagree")
            includeAngular = bool(needsTorque)
        if lanczos_callback is not None:
            raise NotSupportedError(f"{where}: lanczos_callback is not supported by rpyfmm's samplers")
        eta = _real(viscosity, "viscosity", where, 0.0)
        a = _real(hydrodynamicRadius, "hydrodynamicRadius", where, 0.0)
        tol = _real(tolerance, "tolerance", where, 0.0)
        if tol >= 1.0:
            raise InvalidArgumentError(f"{where}: tolerance must be < 1 (got {tol:g})")
        kT = None if temperature is None else _real(temperature, "temperature", where, 0.0, strict=False)
        if numberParticles is not None and (
                isinstance(numberParticles, (bool, np.bool_)) or not isinstance(numberParticles, numbers.Integral)
                or numberParticles < 1):
            raise InvalidArgumentError(f"{where}: numberParticles must be a positive integer (got {numberParticles!r})")
        if seed is None or seed == 0:
            seed = secrets.randbits(63)
        elif isinstance(seed, (bool, np.bool_)) or not isinstance(seed, numbers.Integral) or seed < 0:
            raise InvalidArgumentError(f"{where}: seed must be None or a non-negative integer (got {seed!r})")
        self._check_parameters_for_initialize()
        op = self._make_operator(eta, tol)
        if includeAngular and not op.supports_rotation:
            raise NotSupportedError(
                f"{where}: includeAngular=True (torques) is not supported by rpyfmm's {op.name} operator")
        self._op = op
        self._radius = a
        self._tolerance = tol
        self._angular = bool(includeAngular)
        self._temperature = kT
        self._number_particles = None if numberParticles is None else int(numberParticles)
        self._seed = int(seed)
        self._calls = 0
        self._n = 0
        self._like = None
        self._host_like = None
        self._initialized = True

    def setPositions(self, positions: npt.ArrayLike) -> None:
        """Positions (N, 3) or (3N,), length units; later results take this shape when no forces are given."""
        where = f"{type(self).__name__}.setPositions"
        self._require_initialized(where)
        if self._device_arrays and _dlpack_device(positions) is not None:
            self._set_device_positions(positions, where)
            return
        x, shape = _flat3(positions, "positions", where)
        self._check_number(len(x), where)
        self._op.set_positions(x, self._radius)
        self._n = len(x)
        self._shape = shape
        self._like = None
        self._host_like = _host_framework(positions)

    def Mdot(self, forces: Optional[npt.ArrayLike] = None,
             torques: Optional[npt.ArrayLike] = None) -> Velocities:
        """(U, W) = M (F, T): velocities in the shape of the forces, angular velocities (None without
        includeAngular). At least one of forces and torques; torques need includeAngular=True."""
        where = f"{type(self).__name__}.Mdot"
        if self._device_call(where, forces=forces, torques=torques):
            return self._device_apply(forces, torques, where, need_one=True)
        f, t, f_shape, t_shape = self._loads(forces, torques, where, need_one=True)
        u, w = self._apply(f, t)
        return self._results(u, w, f_shape, t_shape, forces if forces is not None else torques)

    def sqrtMdotW(self, prefactor: float = 1.0) -> Velocities:
        """prefactor * M^{1/2} xi (libMobility 1.x) or, after initialize(temperature=kT),
        prefactor * sqrt(2 kT M) xi (before 0.9); xi standard normal. Shapes of the positions."""
        where = f"{type(self).__name__}.sqrtMdotW"
        self._require_positions(where)
        scale = self._noise_scale(_real(prefactor, "prefactor", where))
        if self._like is not None:
            return self._device_sqrt(scale, where)
        u, w = self._sqrt(scale)
        return self._results(u, w, self._shape, self._shape, None)

    def LangevinVelocities(self, dt: float, kbt: float, forces: Optional[npt.ArrayLike] = None,
                           torques: Optional[npt.ArrayLike] = None) -> Velocities:
        """M (F, T) + sqrt(2 kbt / dt) M^{1/2} xi + kbt div M (the divergence is zero here). Without
        forces and torques only the noise; kbt = 0: only M (F, T)."""
        where = f"{type(self).__name__}.LangevinVelocities"
        step = _real(dt, "dt", where, 0.0)
        kT = _real(kbt, "kbt", where, 0.0, strict=False)
        scale = math.sqrt(2.0 * kT / step)
        if not math.isfinite(scale):  # a subnormal dt: the noise would be infinite
            raise InvalidArgumentError(f"{where}: sqrt(2 kbt / dt) overflows for dt = {step:g} and kbt = {kT:g}")
        return self._velocities(forces, torques, where, scale)

    def divM(self, prefactor: float = 1.0) -> Velocities:
        """prefactor * div M: zero for these solvers (one radius, free space or a periodic box)."""
        where = f"{type(self).__name__}.divM"
        self._require_positions(where)
        c = _real(prefactor, "prefactor", where)
        if self._like is not None:  # div M = 0 (one radius, periodic box), as divergence() gives on the host
            return self._device_zeros()
        u, w = self._zeros()
        u += c * self._op.divergence()
        return self._results(u, w, self._shape, self._shape, None)

    def hydrodynamicVelocities(self, forces: Optional[npt.ArrayLike] = None, torques: Optional[npt.ArrayLike] = None,
                               prefactor: float = 1.0) -> Velocities:
        """libMobility before 0.9: M (F, T) + prefactor * sqrt(2 kT M) xi (+ prefactor kT div M, zero here),
        kT from initialize(temperature=...)."""
        where = f"{type(self).__name__}.hydrodynamicVelocities"
        self._require_temperature(where, "LangevinVelocities(dt, kbt, forces, torques)")
        c = _real(prefactor, "prefactor", where)
        return self._velocities(forces, torques, where, self._noise_scale(c))

    def thermalDrift(self, prefactor: float = 1.0) -> Velocities:
        """libMobility before 0.9: prefactor * kT div M (zero here), kT from initialize(temperature=...)."""
        where = f"{type(self).__name__}.thermalDrift"
        self._require_temperature(where, "divM(prefactor)")
        return self.divM(_real(prefactor, "prefactor", where) * self._temperature)

    def clean(self) -> None:
        """Frees the operator; initialize must be called again before use."""
        self._op = None
        self._initialized = False
        self._n = 0
        self._like = None
        self._host_like = None

    def getNumberParticles(self) -> int:
        """N of the last setPositions (0 before)."""
        return self._n

    def __repr__(self) -> str:
        state = f"N = {self._n}" if self._initialized else "not initialized"
        return f"<rpyfmm.libmobility.{type(self).__name__} ({', '.join(self._geometry)}), {state}>"

    # -- helpers -----------------------------------------------------------------------------
    def _set_parameters(self, **values: Any) -> None:
        self._params.update(values)
        self._parameters_set = True

    def _check_parameters_for_initialize(self) -> None:
        pass

    def _require_initialized(self, where: str) -> None:
        if not self._initialized:
            raise InvalidArgumentError(f"{where}: call initialize first (after setParameters)")

    def _require_positions(self, where: str) -> None:
        self._require_initialized(where)
        if self._n == 0:
            raise InvalidArgumentError(f"{where}: call setPositions first")

    def _require_temperature(self, where: str, instead: str) -> None:
        self._require_initialized(where)
        if self._temperature is None:
            raise NotSupportedError(
                f"{where} is libMobility's spelling before 0.9 and needs initialize(temperature=...); "
                f"with initialize(viscosity, hydrodynamicRadius, ...) use {instead}")

    def _check_number(self, n: int, where: str) -> None:
        if self._number_particles is not None and n != self._number_particles:
            raise InvalidInputError(f"{where}: {n} positions, but initialize(numberParticles={self._number_particles})")

    def _noise_scale(self, prefactor: float) -> float:
        if self._temperature is None:
            return prefactor
        return prefactor * math.sqrt(2.0 * self._temperature)

    def _check_loads(self, forces: Any, torques: Any, where: str, need_one: bool) -> None:
        """Positions set, forces and/or torques given as the call needs, torques only with includeAngular."""
        self._require_positions(where)
        if need_one and forces is None and torques is None:
            raise InvalidArgumentError(f"{where}: give forces, torques or both")
        if torques is not None and not self._angular:
            raise InvalidArgumentError(
                f"{where}: torques given but the solver was initialized with includeAngular=False")

    def _loads(self, forces: Optional[npt.ArrayLike], torques: Optional[npt.ArrayLike], where: str,
               need_one: bool) -> Tuple[ArrayOrNone, ArrayOrNone, Tuple[int, ...], Tuple[int, ...]]:
        self._check_loads(forces, torques, where, need_one)
        f = t = None
        f_shape = t_shape = self._shape
        if forces is not None:
            f, f_shape = _flat3(forces, "forces", where)
        if torques is not None:
            t, t_shape = _flat3(torques, "torques", where)
        for name, a in (("forces", f), ("torques", t)):
            if a is not None and len(a) != self._n:
                raise InvalidInputError(f"{where}: {name} has {3 * len(a)} entries, expected 3N = {3 * self._n}")
        if forces is None and torques is not None:
            f_shape = t_shape
        elif torques is None and forces is not None:
            t_shape = f_shape
        return f, t, f_shape, t_shape

    def _velocities(self, forces: Optional[npt.ArrayLike], torques: Optional[npt.ArrayLike], where: str,
                    noise_scale: float) -> Velocities:
        """M (F, T) (zero without forces and torques) + noise_scale * M^{1/2} xi (none for a zero scale)."""
        given = forces is not None or torques is not None
        if self._device_call(where, forces=forces, torques=torques) or (not given and self._like is not None):
            u, w = self._device_apply(forces, torques, where, need_one=False) if given else self._device_zeros()
            if noise_scale != 0.0:
                u += self._device_sqrt(noise_scale, where)[0]
            return u, w
        f, t, f_shape, t_shape = self._loads(forces, torques, where, need_one=False)
        u, w = self._apply(f, t) if (f is not None or t is not None) else self._zeros()
        if noise_scale != 0.0:
            du, dw = self._sqrt(noise_scale)
            u += du
            if w is not None:
                w += dw
        return self._results(u, w, f_shape, t_shape, forces if forces is not None else torques)

    def _zeros(self) -> Tuple[np.ndarray, ArrayOrNone]:
        return np.zeros((self._n, 3)), (np.zeros((self._n, 3)) if self._angular else None)

    def _apply(self, f: ArrayOrNone, t: ArrayOrNone) -> Tuple[np.ndarray, ArrayOrNone]:
        if f is None:
            f = np.zeros((self._n, 3))
        if not self._angular:
            return self._op.apply(f), None
        return self._op.apply(f, np.zeros((self._n, 3)) if t is None else t)

    def _sqrt(self, scale: float) -> Tuple[np.ndarray, ArrayOrNone]:
        step = self._calls
        self._calls += 1
        if scale == 0.0:
            return self._zeros()
        zt = normal_noise(self._n, self._seed, step)
        if self._angular:
            zr = normal_noise(self._n, self._seed, step, stream=_ROTATION_STREAM)
            wt, wr, _ = self._op.apply_sqrt_rotation(zt, zr, tolerance=self._tolerance)
            return scale * wt, scale * wr
        w, _ = self._op.apply_sqrt(zt, tolerance=self._tolerance)
        return scale * w, None

    # -- device arrays (PSE with device="cuda"): the same products as the host path, in place ------
    def _device_call(self, where: str, **arrays: Any) -> bool:
        """True when the given arrays are device arrays the operator takes (all of them; a mix of
        host and device arrays is refused). Device arrays for a host operator take the host path,
        whose _flat3 refuses them."""
        on = {name: _dlpack_device(a) is not None for name, a in arrays.items() if a is not None}
        if not self._device_arrays or not any(on.values()):
            return False
        if not all(on.values()):
            raise InvalidInputError(f"{where}: {' and '.join(on)} must be all device arrays or all host arrays")
        return True

    def _set_device_positions(self, positions: Any, where: str) -> None:
        """Moves the operator to device positions in place; the plan of a new N comes from a host copy
        (PseRpyCuda builds its grids and splitting from host positions, docs/python.md)."""
        _array_module(positions, "positions", where)
        shape = tuple(positions.shape)
        n = math.prod(shape) // 3
        self._check_number(n, where)
        if n != self._n:
            host, shape = _flat3(cuda.to_host(positions), "positions", where)
            self._op.set_positions(host, self._radius)
        else:
            self._op.set_positions(positions, self._radius)  # shape, size and values checked there
        self._n, self._shape, self._like = n, shape, positions

    def _device_apply(self, forces: Any, torques: Any, where: str, need_one: bool) -> Tuple[Any, Any]:
        """M (F, T) on device arrays, in their framework; a missing one of F, T is zero."""
        self._check_loads(forces, torques, where, need_one)
        given, name = (forces, "forces") if forces is not None else (torques, "torques")
        xp = _array_module(given, name, where)
        f = xp.zeros_like(torques) if forces is None else forces
        if not self._angular:
            return self._op.apply(f), None
        return self._op.apply(f, xp.zeros_like(f) if torques is None else torques)

    def _device_zeros(self) -> Tuple[Any, Any]:
        xp = _array_module(self._like, "positions", "zeros")
        return xp.zeros_like(self._like), (xp.zeros_like(self._like) if self._angular else None)

    def _device_sqrt(self, scale: float, where: str) -> Tuple[Any, Any]:
        """scale * M^{1/2} xi written on the device in the positions' framework, by the operator's
        sample (keyed by (seed, call), as the host path of the CUDA solver)."""
        if self._angular:
            raise NotSupportedError(
                f"{where}: with includeAngular=True the noise takes host arrays (the rotational square root "
                "has no device entry point); device arrays are taken by Mdot")
        step = self._calls
        self._calls += 1
        w, _ = self._device_zeros()
        if scale != 0.0:
            self._op.sample(self._seed, step, out=w)
            w *= scale
        return w, None

    def _results(self, u: np.ndarray, w: ArrayOrNone, u_shape: Tuple[int, ...], w_shape: Tuple[int, ...],
                 given: Any) -> Tuple[Any, Any]:
        """(U, W) in the given shapes, as NumPy arrays or in the framework of the host array `given`
        (of the positions' where the call has none): a PyTorch CPU tensor in, PyTorch tensors out."""
        wrap = _host_framework(given) if given is not None else self._host_like
        u, w = u.reshape(u_shape), (None if w is None else w.reshape(w_shape))
        if wrap is None:
            return u, w
        return wrap(np.ascontiguousarray(u)), (None if w is None else wrap(np.ascontiguousarray(w)))


class NBody(_Solver):
    """RPY mobility in free space (libMobility's NBody with periodicity open, open, open).

    rpyfmm evaluates it by the exact O(N^2) sum (DirectRpy) or the O(N) FMM (FmmRpy):
    setParameters(algorithm="advise") picks by N as make_mobility("auto") does,
    "direct" / "naive" / "fast" / "block" the exact sum, "fmm" the FMM. Torques with
    includeAngular=True (the grand mobility)."""

    def _geometry_note(self, given: Tuple[str, str, str]) -> str:
        if given[2] in ("single_wall", "two_walls"):
            return " (rpyfmm has no wall mobility)"
        return ""

    def _default_parameters(self) -> Dict[str, Any]:
        return {"algorithm": "advise"}

    def setParameters(self, algorithm: str = "advise", Nbatch: int = -1, NperBatch: int = -1,
                      wallHeight: Optional[float] = None, delta: float = 1e-3) -> None:
        """algorithm: "advise" (default: direct or FMM by N), "naive", "fast", "block" (all: the exact
        direct sum), or rpyfmm's "direct" / "fmm". Nbatch / NperBatch: one batch only (-1 or 1 /
        -1 or N). wallHeight: not supported (no wall). delta: accepted and unused (no drift in free
        space). Takes effect at the next initialize."""
        where = "NBody.setParameters"
        names = ("advise", "naive", "fast", "block", "direct", "fmm")
        if algorithm not in names:
            raise InvalidArgumentError(f"{where}: algorithm = {algorithm!r}, expected one of {', '.join(names)}")
        if wallHeight is not None:
            raise NotSupportedError(f"{where}: wallHeight (the single-wall mobility) is not supported by rpyfmm")
        for name, v in (("Nbatch", Nbatch), ("NperBatch", NperBatch)):
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Integral):
                raise InvalidArgumentError(f"{where}: {name} must be an integer (got {v!r})")
        if Nbatch not in (-1, 1):
            raise NotSupportedError(
                f"{where}: Nbatch = {Nbatch} (independent batches of particles) is not supported; use -1 or 1")
        _real(delta, "delta", where, 0.0)
        self._set_parameters(algorithm=algorithm, NperBatch=int(NperBatch))

    setParametersNBody = setParameters

    def setPositions(self, positions: npt.ArrayLike) -> None:
        if _dlpack_device(positions) is not None:
            _flat3(positions, "positions", "NBody.setPositions")  # refuses it, before any conversion
        per = self._params.get("NperBatch", -1)
        n = np.asarray(positions).size // 3
        if per != -1 and n != per:
            raise NotSupportedError(
                f"NBody.setPositions: NperBatch = {per} but {n} particles (one batch only)")
        if self._initialized and self._params["algorithm"] == "advise" and n > 0:
            # "advise": the exact sum or the FMM by N, as make_mobility("auto") picks.
            op = make_mobility("auto", n, tolerance=self._fmm_tolerance, viscosity=self._viscosity)
            if op.name != self._op.name:
                self._op = op
        super().setPositions(positions)

    def _make_operator(self, viscosity: float, tolerance: float) -> MobilityOperator:
        algorithm = self._params["algorithm"]
        self._viscosity = viscosity
        self._fmm_tolerance = min(max(tolerance, 1e-12), 1e-1)
        return make_mobility("fmm" if algorithm == "fmm" else "direct", 0, tolerance=self._fmm_tolerance,
                             viscosity=viscosity)


class PSE(_Solver):
    """RPY mobility in a triply periodic box by Positively Split Ewald (libMobility's PSE), rpyfmm's
    PseRpy. setParameters(psi, Lx, Ly, Lz) is required. includeAngular=True gives PseRpy's grand
    mobility with rotation (libMobility's PSE refuses torques)."""

    _geometry = ("periodic", "periodic", "periodic")

    def setParameters(self, psi: float, Lx: float, Ly: float, Lz: float,
                      shearStrain: Optional[float] = None, *, device: str = "cpu") -> None:
        """psi: Ewald splitting parameter (1/length; rpyfmm's xi; 0 = automatic); Lx, Ly, Lz: box
        sides. shearStrain: not supported (None or 0 only). device (rpyfmm's, keyword only): "cpu"
        (PseRpy) or "cuda" (PseRpyCuda: CuPy / PyTorch device arrays read in place, see the module
        docstring; NotSupportedError at initialize without a usable GPU). Takes effect at the next
        initialize."""
        where = "PSE.setParameters"
        xi = _real(psi, "psi", where, 0.0, strict=False)
        box = tuple(_real(v, n, where, 0.0) for n, v in (("Lx", Lx), ("Ly", Ly), ("Lz", Lz)))
        if shearStrain is not None and _real(shearStrain, "shearStrain", where) != 0.0:
            raise NotSupportedError(f"{where}: shearStrain (a sheared box) is not supported by rpyfmm's PSE")
        if device not in ("cpu", "cuda"):
            raise InvalidArgumentError(f"{where}: device = {device!r}, expected 'cpu' or 'cuda'")
        self._set_parameters(xi=xi, box=box, device=device)

    setParametersPSE = setParameters

    def _check_parameters_for_initialize(self) -> None:
        if not self._parameters_set:
            raise InvalidArgumentError("PSE.initialize: call setParameters(psi, Lx, Ly, Lz) first")

    def _make_operator(self, viscosity: float, tolerance: float) -> MobilityOperator:
        kind = PseRpyCuda if self._params["device"] == "cuda" else PseRpy
        op = kind(box=self._params["box"], viscosity=viscosity, tolerance=min(max(tolerance, 1e-8), 0.099),
                  xi=self._params["xi"])
        self._device_arrays = kind is PseRpyCuda
        return op

    def _sqrt(self, scale: float) -> Tuple[np.ndarray, ArrayOrNone]:
        if not self._device_arrays or self._angular:
            return super()._sqrt(scale)
        # The CUDA operator's sampler, keyed by (seed, call) as on device arrays: the same numbers.
        step = self._calls
        self._calls += 1
        if scale == 0.0:
            return self._zeros()
        w, _ = self._op.sample(self._seed, step)
        return scale * w, None


class SelfMobility(_Solver):
    """No hydrodynamic interactions (libMobility's SelfMobility): M = I / (6 pi eta a), rotation
    I / (8 pi eta a^3); rpyfmm's FreeDraining. Open boundaries."""

    def setParameters(self, parameter: float = 0.0) -> None:
        """libMobility's example parameter: accepted and unused, as there."""
        _real(parameter, "parameter", "SelfMobility.setParameters")
        self._set_parameters()

    setParametersSelfMobility = setParameters

    def _make_operator(self, viscosity: float, tolerance: float) -> MobilityOperator:
        return FreeDraining(viscosity=viscosity)


class DPStokes:
    """libMobility's doubly periodic Stokes solver: not available in rpyfmm (refused on construction)."""

    precision = "double"

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        raise NotSupportedError(
            "DPStokes: doubly periodic geometries (periodic in X and Y; open, single_wall or two_walls in Z) "
            "are not supported by rpyfmm; it offers free space (NBody) and triply periodic boxes (PSE)")

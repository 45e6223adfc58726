"""fmm3dpy-compatible Laplace FMM: ``from rpyfmm.fmm3d import lfmm3d``.

A drop-in for ``fmm3dpy.lfmm3d`` (FMM3D's Python interface, version 2.x) on top
of :class:`rpyfmm.LaplaceFmm`: the same keyword names, array layouts, output
object and kernel, so that code written for fmm3dpy runs by changing the import.

Kernel. As fmm3dpy 2.x (FMM3D >= 2.0), the potential of charges c_j at sources
x_j is

    u(x) = sum_j c_j / (4 pi |x - x_j|)

with the term x = x_j dropped (the self pair, and a target coinciding with a
source). ``grad`` is the gradient of u and ``hess`` its Hessian. rpyfmm's own
:class:`~rpyfmm.LaplaceFmm` and :func:`~rpyfmm.laplace_direct` sum c_j / |x - x_j|
without the 1/(4 pi); this module multiplies by 1/(4 pi). fmm3dpy 1.0.0 (FMM3D
< 2.0) used the kernel 1/r: multiply the results by 4 pi to reproduce it.

Layouts (fmm3dpy's): sources (3, n); targets (3, nt); charges (n,) for nd = 1
or (nd, n). Outputs for nd = 1: pot (n,), grad (3, n), hess (6, n) in the
order xx, yy, zz, xy, xz, yz; pottarg, gradtarg, hesstarg likewise with nt.
For nd > 1 each gains a leading nd axis: pot (nd, n), grad (nd, 3, n),
hess (nd, 6, n). pg / pgt = 1: potential, 2: potential and gradient, 3: also
the Hessian; outputs not requested stay None.

What differs from fmm3dpy:

* Only charges: ``dipvec`` (dipoles) raises NotSupportedError naming it.
* Requests fmm3dpy refuses or ignores work here: pg and pgt may differ (fmm3dpy
  asserts they are equal when both are set); pgt > 0 without targets raises
  InvalidArgumentError (fmm3dpy returns no target outputs).
* pg = pgt = 0 returns an empty Output without printing a note.
* eps is clamped to rpyfmm's range [1e-15, 1e-1] (a larger eps gets 1e-1, a
  smaller one the full double-precision accuracy that 1e-15 requests); the
  error of each output is that of rpyfmm.LaplaceFmm: at most eps times the
  norm of the charges' absolute field, the relative l2 error where the field
  does not cancel (docs/theory/fmm.md, Sec. 7).
* Inputs are checked first: wrong shapes, non-finite values and bad flags raise
  :class:`rpyfmm.InvalidArgumentError` (a ValueError) with a message in
  fmm3dpy's layout, where fmm3dpy raises AssertionError.
* Only ``lfmm3d`` is mirrored: fmm3dpy's direct sum ``l3ddir``, the Helmholtz,
  Stokes and Maxwell FMMs have no counterpart here (rpyfmm.laplace_direct is the
  direct 1/r sum in rpyfmm's own layout).
"""

from __future__ import annotations

import math
import numbers
from typing import Optional, Tuple

import numpy as np
import numpy.typing as npt

from ._rpyfmm import InvalidArgumentError, LaplaceFmm, NotSupportedError

__all__ = ["Output", "lfmm3d"]

_INV_4PI = 1.0 / (4.0 * math.pi)
_EPS_RANGE = (1e-15, 1e-1)  # LaplaceFmm's tolerance range
_OUTPUT_NAMES = {1: "potential", 2: "potential|gradient", 3: "all"}


class Output:
    """Results of :func:`lfmm3d` (fmm3dpy's ``Output``): ``pot``, ``grad``, ``hess`` at the
    sources and ``pottarg``, ``gradtarg``, ``hesstarg`` at the targets, None where not
    requested; ``ier`` is 0 (errors raise instead)."""

    def __init__(self) -> None:
        self.pot: Optional[np.ndarray] = None
        self.grad: Optional[np.ndarray] = None
        self.hess: Optional[np.ndarray] = None
        self.pottarg: Optional[np.ndarray] = None
        self.gradtarg: Optional[np.ndarray] = None
        self.hesstarg: Optional[np.ndarray] = None
        self.ier: int = 0

    def __repr__(self) -> str:
        set_names = [k for k in ("pot", "grad", "hess", "pottarg", "gradtarg", "hesstarg") if getattr(self, k) is not None]
        return f"<rpyfmm.fmm3d.Output: {', '.join(set_names) or 'empty'}>"


def _fail(message: str) -> None:
    raise InvalidArgumentError(f"lfmm3d: {message}")


def _flag(value: object, name: str) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or int(value) not in (0, 1, 2, 3):
        _fail(f"{name} must be 0, 1, 2 or 3 (got {value!r})")
    return int(value)


def _real_array(value: object, name: str) -> np.ndarray:
    a = np.asarray(value)
    if a.dtype.kind not in "biuf":
        _fail(f"{name} must be a real array (got dtype {a.dtype})")
    a = np.asarray(a, dtype=np.float64)
    if not np.isfinite(a).all():
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
        _fail(f"{name} entry {bad} is {a[bad]} (values must be finite)")
    return a


def _points(value: object, name: str) -> np.ndarray:
    """(3, n) (or (3,) for one point) -> (n, 3) C-contiguous."""
    a = _real_array(value, name)
    if a.ndim == 1 and a.shape[0] == 3:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] != 3 or a.shape[1] == 0:
        _fail(f"{name} has shape {a.shape}, expected (3, n) with n >= 1 (fmm3dpy's layout)")
    return np.ascontiguousarray(a.T)


def _charges(value: object, nd: int, ns: int) -> np.ndarray:
    q = _real_array(value, "charges")
    if nd == 1:
        if q.ndim == 0 and ns == 1:
            q = q.reshape(1)
        if q.shape != (ns,):
            _fail(f"charges has shape {q.shape}, expected ({ns},) for nd = 1 and {ns} sources")
    elif q.shape != (nd, ns):
        _fail(f"charges has shape {q.shape}, expected (nd, n) = ({nd}, {ns})")
    return np.ascontiguousarray(q)


def _eps(value: object) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)) or float(value) <= 0.0:
        _fail(f"eps must be a positive finite number (got {value!r})")
    return min(max(float(value), _EPS_RANGE[0]), _EPS_RANGE[1])


def _split(r: np.ndarray, level: int) -> Tuple[np.ndarray, Optional[np.ndarray], Optional[np.ndarray]]:
    """rpyfmm's (..., M, 10) block -> fmm3dpy's pot (..., M), grad (..., 3, M), hess (..., 6, M)."""
    pot = np.ascontiguousarray(r[..., 0]) * _INV_4PI
    grad = np.ascontiguousarray(np.swapaxes(r[..., 1:4], -1, -2)) * _INV_4PI if level >= 2 else None
    hess = np.ascontiguousarray(np.swapaxes(r[..., 4:10], -1, -2)) * _INV_4PI if level >= 3 else None
    return pot, grad, hess


def lfmm3d(
    *,
    eps: float,
    sources: npt.ArrayLike,
    charges: Optional[npt.ArrayLike] = None,
    dipvec: Optional[npt.ArrayLike] = None,
    targets: Optional[npt.ArrayLike] = None,
    pg: int = 0,
    pgt: int = 0,
    nd: int = 1,
) -> Output:
    """Laplace N-body sums by the FMM with fmm3dpy's interface (module docstring).

    u(x) = sum_j charges_j / (4 pi |x - sources_j|), the self pair dropped.

    Args:
      eps: requested relative accuracy (clamped to [1e-15, 1e-1]).
      sources: (3, n) source locations.
      charges: (n,) for nd = 1, (nd, n) for nd > 1. Required.
      dipvec: not supported (NotSupportedError when given).
      targets: (3, nt) target locations, or None.
      pg: outputs at the sources: 0 none, 1 potential, 2 + gradient, 3 + Hessian.
      pgt: the same at the targets (needs targets).
      nd: number of charge vectors sharing the sources.

    Returns:
      Output with pot/grad/hess (sources) and pottarg/gradtarg/hesstarg (targets)
      set as requested, float64, in fmm3dpy's layout.
    """
    if dipvec is not None:
        raise NotSupportedError(
            "lfmm3d: dipvec (dipole sources) is not supported by rpyfmm's Laplace FMM; only charges are")
    tolerance = _eps(eps)
    pg = _flag(pg, "pg")
    pgt = _flag(pgt, "pgt")
    if isinstance(nd, (bool, np.bool_)) or not isinstance(nd, numbers.Integral) or nd < 1:
        _fail(f"nd must be a positive integer (got {nd!r})")
    nd = int(nd)
    src = _points(sources, "sources")
    if charges is None:
        _fail("charges is required (dipole sources, dipvec, are not supported)")
    q = _charges(charges, nd, len(src))
    tgt = _points(targets, "targets") if targets is not None else None
    if pgt > 0 and tgt is None:
        _fail(f"pgt = {pgt} requests outputs at the targets but targets is None")

    out = Output()
    level = max(pg, pgt)
    if level == 0:
        return out
    # One plan: sources and targets as the evaluation points when both are requested (pairs at
    # distance zero, the self pairs among them, contribute nothing, as in fmm3dpy).
    at_sources = pg > 0
    at_targets = pgt > 0
    fmm = LaplaceFmm(tolerance=tolerance)
    if at_sources and at_targets:
        fmm.set_points(src, targets=np.concatenate([src, tgt]))
    else:
        fmm.set_points(src, targets=tgt if at_targets else None)
    r = fmm.evaluate(q if nd > 1 else q.reshape(-1), outputs=_OUTPUT_NAMES[level])
    ns = len(src)
    if at_sources:
        out.pot, out.grad, out.hess = _split(r[..., :ns, :], pg)
    if at_targets:
        start = ns if at_sources else 0
        out.pottarg, out.gradtarg, out.hesstarg = _split(r[..., start:, :], pgt)
    return out

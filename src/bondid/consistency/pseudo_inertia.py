"""Dynamic parameters of one rigid body, their URDF form and the 4x4 pseudo-inertia.

Conventions (shared by the whole ``bondid.consistency`` package):

* ``pi`` — numpy array (10,), Pinocchio's order
  ``[m, m·cx, m·cy, m·cz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` (kg, kg·m, kg·m²) with the rotational
  inertia ``Ī`` taken about the LINK FRAME ORIGIN and expressed in the link frame, as
  ``pinocchio.Inertia.toDynamicParameters()`` returns it.
* URDF form — mass ``m`` (kg), centre of mass ``c`` (3,) (m) and inertia about the CoM ``I_c``
  (3, 3) (kg·m²), all in the link frame.
* Pseudo-inertia ``J = [[Σ, h], [hᵀ, m]]`` (4, 4) with ``Σ = ½ tr(Ī) 𝟙 − Ī`` (the second moment
  of the mass distribution about the origin, kg·m²) and ``h = m·c``. ``J ≻ 0`` is equivalent to
  full physical consistency (Wensing, Kim & Slotine 2018): ``m > 0`` and the second moment about
  the CoM ``Σ_c = Σ − h hᵀ / m = ½ tr(I_c) 𝟙 − I_c ≻ 0`` — that is ``I_c ≻ 0`` together with the
  strict triangle inequalities between its principal moments.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bondid.exceptions import ParameterError

FloatArray = NDArray[np.float64]

#: Default relative tolerance of :func:`is_consistent`.
DEFAULT_TOL = 1e-9

# (row, col) of Ī for pi[4:10], Pinocchio's order Ixx, Ixy, Iyy, Ixz, Iyz, Izz.
_INERTIA_INDEX = ((0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2))


def _label(name: str | None) -> str:
    return f"body {name!r}" if name else "body"


def as_pi(pi: ArrayLike, name: str | None = None) -> FloatArray:
    """Return ``pi`` as a finite float array (10,); raise ParameterError otherwise."""
    arr = np.asarray(pi, dtype=float)
    if arr.shape != (10,):
        raise ParameterError(
            f"{_label(name)}: dynamic parameters must have shape (10,), got {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{_label(name)}: dynamic parameters must be finite, got {arr}")
    return arr


def inertia_from_pi(pi: ArrayLike) -> FloatArray:
    """Rotational inertia about the link origin ``Ī`` (3, 3) kg·m² from ``pi`` (10,)."""
    p = as_pi(pi)
    inertia = np.empty((3, 3))
    for k, (i, j) in enumerate(_INERTIA_INDEX):
        inertia[i, j] = inertia[j, i] = p[4 + k]
    return inertia


def pi_from_parts(mass: float, first_moment: ArrayLike, inertia_origin: ArrayLike) -> FloatArray:
    """Assemble ``pi`` (10,) from ``m`` (kg), ``h = m·c`` (3,) kg·m and ``Ī`` (3, 3) kg·m².

    ``Ī`` is symmetrised (its upper triangle is read after averaging with its transpose).
    """
    h = np.asarray(first_moment, dtype=float).reshape(3)
    inertia = np.asarray(inertia_origin, dtype=float).reshape(3, 3)
    inertia = 0.5 * (inertia + inertia.T)
    pi = np.empty(10)
    pi[0] = float(mass)
    pi[1:4] = h
    for k, (i, j) in enumerate(_INERTIA_INDEX):
        pi[4 + k] = inertia[i, j]
    return pi


def _skew_sq(c: FloatArray) -> FloatArray:
    """``‖c‖² 𝟙 − c cᵀ`` (3, 3): the parallel-axis term per unit mass."""
    return float(c @ c) * np.eye(3) - np.outer(c, c)


def pi_from_urdf(mass: float, com: ArrayLike, inertia_com: ArrayLike) -> FloatArray:
    """Dynamic parameters (10,) from the URDF form.

    Args:
        mass: ``m`` in kg.
        com: centre of mass ``c`` (3,) in m, link frame.
        inertia_com: inertia about the CoM ``I_c`` (3, 3) in kg·m², link frame axes.

    Returns:
        ``pi`` (10,): ``[m, m·c, Ī]`` with ``Ī = I_c + m (‖c‖² 𝟙 − c cᵀ)`` (parallel axis).
    """
    c = np.asarray(com, dtype=float).reshape(3)
    inertia_c = np.asarray(inertia_com, dtype=float).reshape(3, 3)
    m = float(mass)
    return pi_from_parts(m, m * c, inertia_c + m * _skew_sq(c))


def urdf_from_pi(pi: ArrayLike, name: str | None = None) -> tuple[float, FloatArray, FloatArray]:
    """URDF form ``(m, c, I_c)`` of ``pi`` (10,); inverse of :func:`pi_from_urdf`.

    Returns:
        ``m`` (kg), ``c`` (3,) m and ``I_c`` (3, 3) kg·m² about the CoM, link frame axes.

    Raises:
        ParameterError: if ``m <= 0`` (the CoM is then undefined).
    """
    p = as_pi(pi, name)
    m = float(p[0])
    if not m > 0.0:
        raise ParameterError(f"{_label(name)}: mass must be > 0 to define a CoM, got {m:g} kg")
    c = p[1:4] / m
    return m, c, inertia_from_pi(p) - m * _skew_sq(c)


def pseudo_inertia(pi: ArrayLike) -> FloatArray:
    """Pseudo-inertia ``J`` (4, 4) of ``pi`` (10,): ``[[Σ, h], [hᵀ, m]]`` (kg, kg·m, kg·m²),
    by ``pinocchio.PseudoInertia``."""
    import pinocchio as pin

    return np.asarray(pin.PseudoInertia.FromDynamicParameters(as_pi(pi)).toMatrix())


def pi_from_pseudo_inertia(J: ArrayLike) -> FloatArray:
    """Dynamic parameters (10,) of a pseudo-inertia ``J`` (4, 4); inverse of :func:`pseudo_inertia`.

    The map is linear: ``m = J₃₃``, ``h = J[:3, 3]``, ``Ī = tr(Σ) 𝟙 − Σ``. ``J`` is symmetrised,
    then read by ``pinocchio.PseudoInertia``.
    """
    import pinocchio as pin

    Jm = np.asarray(J, dtype=float)
    if Jm.shape != (4, 4):
        raise ParameterError(f"pseudo-inertia must have shape (4, 4), got {Jm.shape}")
    return np.asarray(pin.PseudoInertia.FromMatrix(0.5 * (Jm + Jm.T)).toDynamicParameters())


def second_moment_com(pi: ArrayLike, name: str | None = None) -> FloatArray:
    """Second moment of the mass about the CoM ``Σ_c = ½ tr(I_c) 𝟙 − I_c`` (3, 3) kg·m².

    It is the Schur complement of ``m`` in ``J``; its eigenvalues are the principal second
    moments ``σᵢ = ½ (λⱼ + λₖ − λᵢ)`` of the principal moments ``λ`` of ``I_c``.
    """
    _, _, inertia_c = urdf_from_pi(pi, name)
    return 0.5 * np.trace(inertia_c) * np.eye(3) - inertia_c


def is_consistent(pi: ArrayLike, tol: float = DEFAULT_TOL) -> bool:
    """Whether ``pi`` (10,) is strictly physically consistent (``J ≻ 0``), relative tolerance.

    ``J ≻ 0`` ⇔ ``m > 0`` and ``Σ_c ≻ 0``. The test is ``m > 0`` and
    ``min eig Σ_c > tol · max eig Σ_c`` — independent of the units and of where the link origin
    lies (a test on the eigenvalues of ``J`` itself would depend on both).
    """
    p = np.asarray(pi, dtype=float)
    if p.shape != (10,) or not np.all(np.isfinite(p)) or not p[0] > 0.0:
        return False
    sigma = np.linalg.eigvalsh(second_moment_com(p))
    return bool(sigma[-1] > 0.0 and sigma[0] > tol * sigma[-1])


def consistency_report(pi: ArrayLike, tol: float = DEFAULT_TOL, name: str | None = None) -> str:
    """One-paragraph account of why ``pi`` (10,) is (not) physically consistent.

    Names the failing condition(s): non-finite values, mass, principal moments of ``I_c``,
    triangle inequalities (equivalently the principal second moments ``σ`` about the CoM).
    """
    label = _label(name)
    p = np.asarray(pi, dtype=float)
    if p.shape != (10,):
        return f"{label}: not consistent: expected 10 dynamic parameters, got shape {p.shape}"
    if not np.all(np.isfinite(p)):
        return f"{label}: not consistent: non-finite dynamic parameters {p}"
    if not p[0] > 0.0:
        return f"{label}: not consistent: mass m = {p[0]:g} kg is not > 0"
    m, c, inertia_c = urdf_from_pi(p)
    lam = np.linalg.eigvalsh(inertia_c)
    sigma = np.linalg.eigvalsh(0.5 * np.trace(inertia_c) * np.eye(3) - inertia_c)
    head = (
        f"{label}: m = {m:g} kg, CoM = {np.array2string(c, precision=6)} m, principal moments "
        f"of I_c = {np.array2string(lam, precision=6)} kg·m²"
    )
    problems = []
    if lam[0] <= 0.0:
        problems.append(f"I_c is not positive definite (smallest principal moment {lam[0]:.3g})")
    triangle = lam[0] + lam[1] - lam[2]
    if triangle <= tol * max(lam[2], 0.0):
        problems.append(
            f"triangle inequality violated: {lam[0]:.6g} + {lam[1]:.6g} - {lam[2]:.6g} "
            f"= {triangle:.3g} is not > 0"
        )
    if not (sigma[-1] > 0.0 and sigma[0] > tol * sigma[-1]):
        problems.append(
            f"principal second moments about the CoM {np.array2string(sigma, precision=6)} "
            f"kg·m² are not all > {tol:g}·max"
        )
    if not problems:
        return f"{head}: physically consistent (J is positive definite)"
    return f"{head}: not consistent: " + "; ".join(problems)

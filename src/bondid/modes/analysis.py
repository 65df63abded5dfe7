"""Modal analysis of a linearised machine (first-order form, damping not proportional).

For ``M q̈ + D q̇ + K q = B u``, ``y = C q`` the state matrix ``A`` of
:meth:`bondid.linear.LinearModel.state_space` (x = [q, q̇]) is decomposed as
``A X = X Λ`` with left eigenvectors ``Yᴴ A = Λ Yᴴ``. Then, when ``A`` is diagonalisable,

    H(s) = C (sI − A)⁻¹ B = Σ_r R_r / (s − λ_r),   R_r = (C x_r)(y_rᴴ B) / (y_rᴴ x_r),

with ``R_r`` the modal residue ``(n_out, n_in)`` (FRF units × 1/s, independent of how the
eigenvectors are scaled). Each mode is listed once (one member of a conjugate pair, Im λ > 0):

* ``f_hz = |λ| / 2π`` and ``zeta = −Re λ / |λ|`` (rigid-body modes, λ ≈ 0: ``f_hz = 0``,
  ``zeta = None``);
* ``shape``: the displacement part of ``x_r`` (nv,), complex, scaled so that its entry of
  largest magnitude is exactly 1 (real); entries in m or rad per the DOF's joint type;
* ``participation`` (n_out, n_in): how strongly the mode shows in channel OUT.IN — the
  magnitude of the mode's own terms of the expansion above (both members of a pair) evaluated
  at ``s = jω_r``, ``ω_r = |Im λ|`` for a pair (its damped frequency) and ``|λ|`` for a real
  λ (its corner frequency). For a lightly damped mode this is ``≈ |R_r| / |Re λ_r|``: the
  height of its resonance peak in the receptance, in the channel's units (m/N, rad/(N·m),
  ...). ``NaN`` for rigid-body modes (unbounded).
* ``dominance`` (n_out, n_in): ``participation / |H(jω_r)|``, unit-free: ≈ 1 where the mode
  makes the channel's response at its own frequency, ≪ 1 where it is invisible there. It can
  exceed 1 when other modes cancel part of it. ``NaN`` for rigid modes and where H = 0.
* ``energy_share`` (nv,): per-DOF share ``Re(φ̄_j (K φ)_j) / Re(φᴴ K φ)`` of the strain
  energy for vibrating modes, of the kinetic energy (M instead of K) for rigid and real
  modes; ``dominant_dof`` is the DOF with the largest share.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..exceptions import ComputationError
from ..linear.linear_model import LinearModel

RIGID_RTOL = 1e-9
"""λ is a rigid-body eigenvalue when |λ| ≤ RIGID_RTOL · max |λ| (or |λ| ≤ 1e-12 s⁻¹)."""
REAL_RTOL = 1e-9
"""λ is real (not one of a conjugate pair) when |Im λ| ≤ REAL_RTOL · |λ|."""

VISIBLE = 0.5
"""The table lists the channels where a mode's dominance is at least this."""


@dataclass(frozen=True)
class Mode:
    """One mode of the linearised model (one member of a conjugate pair).

    Attributes:
        index: 1-based position in the table (lowest |λ| first).
        eigenvalue: λ [1/s] (Im λ ≥ 0).
        f_hz: |λ| / 2π [Hz]; 0 for rigid-body modes.
        zeta: −Re λ / |λ| (dimensionless); ``None`` for rigid-body modes.
        kind: ``"rigid"`` (λ ≈ 0), ``"real"`` (real λ ≠ 0: overdamped / velocity decay) or
            ``"vibration"`` (complex pair).
        shape: displacement mode shape ``(nv,)`` complex, largest entry = 1.
        residue: modal residue R ``(n_out, n_in)`` complex (FRF units / s).
        participation: ``(n_out, n_in)`` peak contribution (FRF units), NaN for rigid modes.
        dominance: ``(n_out, n_in)`` participation / |H| at the mode's frequency (unit-free).
        energy_share: ``(nv,)`` energy share per DOF (strain or kinetic, see module doc).
        dominant_dof: name of the DOF with the largest energy share.
    """

    index: int
    eigenvalue: complex
    f_hz: float
    zeta: float | None
    kind: str
    shape: np.ndarray
    residue: np.ndarray
    participation: np.ndarray
    dominance: np.ndarray
    energy_share: np.ndarray
    dominant_dof: str

    @property
    def omega(self) -> float:
        """|λ| [rad/s]."""
        return abs(self.eigenvalue)


@dataclass
class ModalResult:
    """All modes of one linear model, lowest first, with the names needed to read them.

    Attributes:
        modes: the modes, lowest |λ| first.
        dofs: DOF (joint) names, length nv, the order of every ``shape``.
        inputs, outputs: joint names of the FRF inputs and outputs.
        operating_point: the named joint values (m or rad) of the linearisation.
        q0: the configuration ``(nq,)``.
        html: mode index → relative path of its animation page (filled by the CLI).
    """

    modes: list[Mode]
    dofs: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    operating_point: dict[str, float]
    q0: np.ndarray
    html: dict[int, str] = field(default_factory=dict)

    @property
    def channels(self) -> list[str]:
        """Channel names ``OUT.IN`` in row-major (output, input) order."""
        return [f"{o}.{i}" for o in self.outputs for i in self.inputs]

    def mode(self, index: int) -> Mode:
        """The mode with 1-based ``index``; raises ``IndexError`` naming the valid range."""
        if not 1 <= index <= len(self.modes):
            raise IndexError(f"mode {index} does not exist; valid: 1..{len(self.modes)}")
        return self.modes[index - 1]

    def vibration_modes(self) -> list[Mode]:
        return [m for m in self.modes if m.kind == "vibration"]

    def frf(self, freq_hz: np.ndarray) -> np.ndarray:
        """Receptance ``(n_out, n_in, n_freq)`` rebuilt from the modal expansion.

        Rigid-body modes (λ = 0) contribute R/s; equals ``LinearModel.frf`` when ``A`` is
        diagonalisable and the model has no loss factor (with one, the modes are those of
        its viscous equivalent, :meth:`bondid.linear.linear_model.LinearModel.viscous`, and
        the two agree at the resonances).
        """
        s = 2j * np.pi * np.asarray(freq_hz, dtype=float)
        n_out, n_in = len(self.outputs), len(self.inputs)
        H = np.zeros((n_out, n_in, s.size), dtype=complex)
        for m in self.modes:
            lam = m.eigenvalue
            H += m.residue[:, :, None] / (s - lam)
            if m.kind == "vibration":
                H += np.conj(m.residue)[:, :, None] / (s - np.conj(lam))
        return H

    def table(self) -> str:
        """The mode table as plain text (one line per mode)."""
        lines = [
            f"{'#':>3} {'f [Hz]':>10} {'zeta':>7} {'Re λ [1/s]':>11} {'Im λ [1/s]':>11}"
            f"  {'main DOF':<16} {'share':>5}  makes ≥50 % of |H| in"
        ]
        chans = self.channels
        for m in self.modes:
            zeta = "—" if m.zeta is None else f"{m.zeta:.4f}"
            share = m.energy_share[self.dofs.index(m.dominant_dof)]
            dom = m.dominance.ravel()
            if np.all(np.isnan(dom)):
                strongest = "— (rigid body)"
            else:
                seen = [c for c, v in zip(chans, dom, strict=True) if v >= VISIBLE]
                strongest = " ".join(seen[:6]) + (" …" if len(seen) > 6 else "") or "—"
            lines.append(
                f"{m.index:>3} {m.f_hz:>10.3f} {zeta:>7} {m.eigenvalue.real:>11.4g}"
                f" {m.eigenvalue.imag:>11.4g}  {m.dominant_dof:<16} {share:>5.0%}  {strongest}"
            )
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (spec §4: ``modes`` lowest first with f_hz, zeta, shape)."""
        chans = self.channels
        modes = []
        for m in self.modes:
            part = m.participation.ravel()
            entry: dict[str, Any] = {
                "index": m.index,
                "f_hz": m.f_hz,
                "zeta": m.zeta,
                "kind": m.kind,
                "eigenvalue": {"re": m.eigenvalue.real, "im": m.eigenvalue.imag},
                "shape": {
                    "re": [float(v) for v in m.shape.real],
                    "im": [float(v) for v in m.shape.imag],
                },
                "dominant_dof": m.dominant_dof,
                "energy_share": {
                    d: float(e) for d, e in zip(self.dofs, m.energy_share, strict=True)
                },
                "participation": _channel_dict(chans, part),
                "dominance": _channel_dict(chans, m.dominance.ravel()),
            }
            if m.index in self.html:
                entry["html"] = self.html[m.index]
            modes.append(entry)
        return {
            "operating_point": dict(self.operating_point),
            "q0": [float(v) for v in self.q0],
            "dofs": list(self.dofs),
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
            "participation_definition": (
                "|terms of mode r (both of a conjugate pair) of H(s) = sum R_r/(s - lambda_r)"
                " at s = j w_r|, w_r = |Im lambda_r| (pair) or |lambda_r| (real),"
                " R_r = C x_r y_r^H B / (y_r^H x_r); receptance units"
            ),
            "dominance_definition": "participation / |H(j w_r)| (unit-free)",
            "shape_definition": (
                "displacement part of the right eigenvector of the state matrix, scaled so"
                " that its largest entry is 1; m or rad per DOF"
            ),
            "modes": modes,
        }

    def to_json(self) -> str:
        """:meth:`to_dict` as indented JSON text."""
        return json.dumps(self.to_dict(), indent=2) + "\n"


def _channel_dict(chans: list[str], values: np.ndarray) -> dict[str, float | None]:
    return {c: (None if math.isnan(v) else float(v)) for c, v in zip(chans, values, strict=True)}


def _normalise(phi: np.ndarray) -> np.ndarray:
    k = int(np.argmax(np.abs(phi)))
    if abs(phi[k]) == 0.0:
        return phi.copy()
    out = phi / phi[k]
    out[k] = 1.0
    return out


def _energy_share(phi: np.ndarray, W: np.ndarray) -> np.ndarray:
    e = np.real(np.conj(phi) * (W @ phi))
    total = float(e.sum())
    return e / total if abs(total) > 0 else np.zeros_like(e)


def _receptance(lm: LinearModel, omega: float) -> np.ndarray:
    """C (K + jG − ω²M + jωD)⁻¹ B at one ω [rad/s] ``(n_out, n_in)``; NaN if singular."""
    Z = lm.K - omega**2 * lm.M + 1j * omega * lm.D
    if lm.G is not None:
        Z = Z + 1j * lm.G
    try:
        return lm.C @ np.linalg.solve(Z, lm.B)
    except np.linalg.LinAlgError:
        return np.full((lm.C.shape[0], lm.B.shape[1]), np.nan + 0j)


def modal_analysis(
    lm: LinearModel,
    operating_point: Mapping[str, float] | None = None,
    *,
    rigid_rtol: float = RIGID_RTOL,
) -> ModalResult:
    """Eigenvalues, mode shapes and channel participation of ``lm``.

    Args:
        lm: the linear model (M, K, D, B, C in SI units).
        operating_point: the named joint values it was linearised at (recorded only).
        rigid_rtol: relative tolerance on |λ| for rigid-body modes.

    Returns:
        The modes, lowest |λ| first (see the module docstring for the definitions).

    Raises:
        ComputationError: the mass matrix is singular or the eigenvalues are not finite.
    """
    import scipy.linalg as sl

    try:
        A, Bs, Cs, _ = lm.state_space()
        lam, Yl, Xr = sl.eig(A, left=True, right=True)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ComputationError(f"modal analysis failed: {exc}") from exc
    if not np.all(np.isfinite(lam)):
        raise ComputationError("modal analysis: the state matrix has non-finite eigenvalues")
    scale = float(np.max(np.abs(lam))) if lam.size else 0.0
    rigid_tol = max(rigid_rtol * scale, 1e-12)
    modes: list[Mode] = []
    for r in _listed(lam, rigid_tol):
        kind, lr = _classify(complex(lam[r]), rigid_tol)
        residue = _residue(Xr[:, r], Yl[:, r], Bs, Cs)
        part, dom = _participation(lm, kind, lr, residue)
        phi = _normalise(Xr[: lm.nv, r])
        share = _energy_share(phi, lm.K if kind == "vibration" else lm.M)
        if not np.any(share):
            share = np.abs(phi) ** 2 / max(float(np.sum(np.abs(phi) ** 2)), 1e-300)
        modes.append(
            Mode(
                index=len(modes) + 1, eigenvalue=lr, f_hz=abs(lr) / (2 * math.pi),
                zeta=None if kind == "rigid" else -lr.real / abs(lr), kind=kind, shape=phi,
                residue=residue, participation=part, dominance=dom, energy_share=share,
                dominant_dof=lm.dofs[int(np.argmax(share))],
            )
        )  # fmt: skip
    return ModalResult(
        modes=modes, dofs=tuple(lm.dofs), inputs=tuple(lm.inputs), outputs=tuple(lm.outputs),
        operating_point=dict(operating_point or {}), q0=np.asarray(lm.q0, dtype=float).copy(),
    )  # fmt: skip


def _listed(lam: np.ndarray, rigid_tol: float) -> list[int]:
    """Indices of the eigenvalues listed (rigid, real, and one member of each pair), lowest
    ``|λ|`` first."""
    keep = [
        r for r, lr in enumerate(lam)
        if abs(lr) <= rigid_tol or abs(lr.imag) <= REAL_RTOL * abs(lr) or lr.imag > 0
    ]  # fmt: skip
    return sorted(keep, key=lambda r: (abs(lam[r]), r))


def _classify(lr: complex, rigid_tol: float) -> tuple[str, complex]:
    """``(kind, λ)``: rigid (λ set to 0), real (imaginary part dropped) or vibration."""
    if abs(lr) <= rigid_tol:
        return "rigid", 0j
    if abs(lr.imag) <= REAL_RTOL * abs(lr):
        return "real", complex(lr.real, 0.0)
    return "vibration", lr


def _residue(x: np.ndarray, y: np.ndarray, Bs: np.ndarray, Cs: np.ndarray) -> np.ndarray:
    """``R = C x yᴴ B / (yᴴ x)`` ``(n_out, n_in)``; NaN for a defective eigenvalue."""
    denom = np.vdot(y, x)  # y^H x
    if abs(denom) <= 1e-12 * np.linalg.norm(x) * np.linalg.norm(y):
        return np.full((Cs.shape[0], Bs.shape[1]), np.nan + 0j)
    return np.outer(Cs @ x, np.conj(y) @ Bs) / denom


def _participation(
    lm: LinearModel, kind: str, lr: complex, residue: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(participation, dominance)`` ``(n_out, n_in)`` of a mode (module docstring)."""
    if kind == "rigid":
        part = np.full(residue.shape, np.nan)
        return part, part.copy()
    w_r = abs(lr.imag) if kind == "vibration" else abs(lr)
    s = 1j * w_r
    term = residue / (s - lr)
    if kind == "vibration":
        term = term + np.conj(residue) / (s - np.conj(lr))
    part = np.abs(term)
    h = np.abs(_receptance(lm, w_r))
    with np.errstate(divide="ignore", invalid="ignore"):
        dom = np.where(h > 0, part / np.where(h > 0, h, 1.0), np.nan)
    return part, dom


def match_mode(reference: Mode, candidates: list[Mode]) -> Mode:
    """The candidate whose shape best matches ``reference`` (largest MAC, then nearest f).

    MAC = |φ_aᴴ φ_b|² / (|φ_a|² |φ_b|²); both shapes must have the same DOF order.
    """
    if not candidates:
        raise ComputationError("no modes to match against")

    def key(m: Mode) -> tuple[float, float]:
        a, b = reference.shape, m.shape
        if a.shape != b.shape:
            return (0.0, -abs(m.f_hz - reference.f_hz))
        mac = abs(np.vdot(a, b)) ** 2 / (np.vdot(a, a).real * np.vdot(b, b).real)
        return (round(float(mac), 6), -abs(m.f_hz - reference.f_hz))

    return max(candidates, key=key)

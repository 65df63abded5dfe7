"""A weak prior toward the model's own values, scaled by the noise of the data.

The fit minimises ``‖r‖² + λ P(z)`` instead of ``‖r‖²``. With ``λ = s²``, the noise variance
of one scaled residual entry (``s² = C_noise / n_r``, ``C_noise`` the cost an exact model would
score on these data, :func:`bondid.cost.noise_level.noise_level_cost`), this is the maximum a
posteriori estimate under the prior that the model's values are right to a relative ``τ``
(1σ, :data:`bondid.fit.defaults.DEFAULT_WIDTH`): a combination of parameters that the data
determine to better than ``τ`` goes where the data say (the prior shifts it by a fraction
about ``(σ_data/τ)²`` of the way), one that they do not stays near the model's value instead
of drifting with the noise onto a bound. The same split as
:mod:`bondid.sensitivity.identifiability`'s, made smoothly.

``P`` per fitted body is the log-determinant (Bregman) divergence of its pseudo-inertia from
the model's, ``d(J, J₀) = tr(J₀⁻¹J) − ln det(J₀⁻¹J) − 4`` over ``2τ²`` — twice the KL divergence
of the two bodies' mass distributions seen as Gaussians; it does not depend on the frame, and
it grows without bound as a body's mass distribution collapses onto a plane, a line or a point
(``det J → 0``), which the data can only buy at a cost. With ``J = U Uᵀ`` and ``A = U₀⁻¹U``
(upper triangular, the log-Cholesky factors of :mod:`bondid.consistency.log_cholesky`),
``d = Σ_{i<j} A_ij² + Σ_i (A_ii² − 1 − 2 ln A_ii)``: ten squares, so the prior is ten more
residual rows and the fit stays a least-squares problem (Gauss–Newton Hessian included). A
mass change ``ε`` alone gives ``d ≈ 2ε²``: the mass has the prior std ``τ``.

Each free stiffness or damping with a non-zero model value ``v₀`` adds the row
``(v − v₀)/(τ|v₀|)``; one whose model value is 0, and transducer gains, have no prior.

Two more settings go with the prior: :func:`shape_bounds` (no body may get more than
:data:`SHAPE_FACTOR` thinner or thicker than the model's along any axis) and
:data:`PRIOR_IPOPT`. :func:`prior_rows` wires all of it into a
:class:`~bondid.optim.problem.FitProblem` (its ``extra_rows``, so every problem of a search —
each step, the presolve — gets the prior toward the same model), :func:`with_prior_ipopt` the
IPOPT options; :func:`bondid.fit.solver.fit` and every schedule of
:class:`bondid.optim.schedules.Strategy` use both when ``prior_width > 0``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..consistency.log_cholesky import _U_INDEX, theta_from_pi, upper_factor
from ..consistency.projection import is_feasible, project_feasible
from ..consistency.pseudo_inertia import pi_from_urdf
from ..cost.noise_level import noise_level_cost
from ..cost.problem import FrfProblem
from ..model.document import UrdfDocument
from ..model.parameters import get_parameter, link_inertial
from .layout import Layout
from .variables import BodyBlock, JointVar

if TYPE_CHECKING:  # pragma: no cover - typing only
    from .problem import FitProblem

_SERIES = 1e-4  # |A_ii − 1| below which g and g' use their series
_UPPER = [(i, j) for i in range(4) for j in range(i + 1, 4)]


def _diag_term(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``g(a) = sign(a − 1) √(a² − 1 − 2 ln a)`` and ``g'(a)`` (a > 0), smooth through 1."""
    x = a - 1.0
    near = np.abs(x) < _SERIES
    with np.errstate(invalid="ignore", divide="ignore"):
        f = np.maximum(x * x + 2.0 * x - 2.0 * np.log1p(x), 0.0)
        g = np.sign(x) * np.sqrt(f)
        dg = (a - 1.0 / a) / g
    g = np.where(near, math.sqrt(2.0) * x * (1.0 - x / 6.0), g)
    dg = np.where(near, math.sqrt(2.0) * (1.0 - x / 3.0), dg)
    return g, dg


def _du_dtheta(theta: np.ndarray) -> np.ndarray:
    """``∂U/∂θ_k`` ``(10, 4, 4)`` of :func:`bondid.consistency.log_cholesky.upper_factor`."""
    U = upper_factor(theta)
    out = np.zeros((10, 4, 4))
    out[0] = U  # U = e^α Ũ
    ea = math.exp(theta[0])
    for k, (i, j) in enumerate(_U_INDEX):
        out[1 + k, i, j] = ea * (math.exp(theta[1 + k]) if i == j else 1.0)
    return out


def logdet_rows(theta: np.ndarray, u0_inv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ten rows ``(10,)`` whose squares sum to ``d(J(θ), J₀)`` and their derivatives
    ``(10, 10)`` with respect to θ; ``u0_inv`` = ``U₀⁻¹`` ``(4, 4)``."""
    A = u0_inv @ upper_factor(theta)
    dA = np.einsum("ab,kbc->kac", u0_inv, _du_dtheta(theta))  # (10, 4, 4)
    g, dg = _diag_term(np.diag(A).copy())
    r = np.concatenate([[A[i, j] for i, j in _UPPER], g])
    J = np.empty((10, 10))
    for row, (i, j) in enumerate(_UPPER):
        J[row] = dA[:, i, j]
    for i in range(4):
        J[6 + i] = dg[i] * dA[:, i, i]
    return r, J


@dataclass
class NominalPrior:
    """The prior's residual rows over the fit's decision vector (see the module docstring).

    Attributes:
        width: τ. lam: λ (cost units). noise_cost: ``C_noise``, the cost of an exact model.
        bodies: ``(block, U₀⁻¹)`` per fitted body. joints: ``(joint variable, v₀)``.
    """

    width: float
    lam: float
    noise_cost: float
    n_z: int
    bodies: list[tuple[BodyBlock, np.ndarray]] = field(default_factory=list)
    joints: list[tuple[JointVar, float]] = field(default_factory=list)

    @property
    def size(self) -> int:
        return 10 * len(self.bodies) + len(self.joints)

    def __call__(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows ``(size,)`` (``Σ r² = λ P(z)``) and their Jacobian ``(size, n_z)``."""
        r = np.empty(self.size)
        J = np.zeros((self.size, self.n_z))
        c_body = math.sqrt(self.lam / 2.0) / self.width
        for k, (blk, u0_inv) in enumerate(self.bodies):
            rb, Jt = logdet_rows(blk.theta(z), u0_inv)
            sl = slice(10 * k, 10 * k + 10)
            r[sl] = c_body * rb
            J[sl, blk.offset : blk.offset + 10] = c_body * Jt @ blk.dtheta_dz(z)
        c_joint = math.sqrt(self.lam) / self.width
        for k, (jv, v0) in enumerate(self.joints, start=10 * len(self.bodies)):
            r[k] = c_joint * (jv.scale * z[jv.index] - v0) / abs(v0)
            J[k, jv.index] = c_joint * jv.scale / abs(v0)
        return r, J


def nominal_prior(
    doc: UrdfDocument,
    layout: Layout,
    noise_cost: float,
    n_residuals: int,
    width: float,
    n_z: int | None = None,
) -> NominalPrior:
    """The prior toward ``doc``'s values over ``layout`` (after ``layout.start``).

    Args:
        doc: the model whose values are the prior's centre (a body that is not physically
            consistent, or whose CoM is outside its hull, is projected first).
        layout: the fit's decision vector.
        noise_cost: the cost an exact model would score (``C_noise``); ``n_residuals``: the
            number of data residual entries ``n_r`` (``λ = C_noise / n_r``).
        width: τ > 0.
        n_z: size of the decision vector (default ``layout.size``; more with an FRF
            modifier's entries after the layout's).
    """
    n = layout.size if n_z is None else n_z
    prior = NominalPrior(width, noise_cost / n_residuals, noise_cost, n)
    for blk in layout.blocks:
        pi0 = pi_from_urdf(*link_inertial(doc, blk.link))
        if not is_feasible(pi0, blk.hull):
            pi0 = project_feasible(pi0, blk.hull, name=blk.link)
        u0 = upper_factor(theta_from_pi(pi0, name=blk.link))
        prior.bodies.append((blk, np.linalg.inv(u0)))
    for jv in layout.joints:
        if jv.name_index < 0:
            continue  # a tied member: its leader carries the prior
        v0 = float(get_parameter(doc, jv.name))
        if v0 != 0.0:
            prior.joints.append((jv, v0))
    return prior


def make_prior(
    doc: UrdfDocument,
    layout: Layout,
    problem: FrfProblem,
    width: float,
    notes: list[str],
    n_z: int | None = None,
) -> NominalPrior | None:
    """The fit's prior (None when ``width`` is 0, or with a note when the noise level of the
    problem's cost is not known: kinds other than the log ones, the l1 norm); ``n_z``: see
    :func:`nominal_prior`."""
    if not width > 0:
        return None
    if not layout.blocks and not layout.joints:
        return None
    cost = noise_level_cost(problem)
    if cost is None or not cost > 0:
        notes.append(
            f"no prior toward the model's values: the noise level of the {problem.options.name}"
            " cost is not known (it is for complex_log and log_magnitude with the l2 norm)"
        )
        return None
    return nominal_prior(doc, layout, cost, problem.n_residuals, width, n_z)


#: IPOPT options of a fit with the prior: no second-order correction. Measured on the bundled
#: data (all 50 parameters but the two zero drive stiffnesses, prior 0.25, one run each):
#: with it, IPOPT accepted corrected h-type steps that raised the cost up to sixfold (1.96 →
#: 12.7) and bounced for 100 iterations (198 iterations, 72 s); without, 94 iterations, 25 s,
#: the same optimum (cost 1.782378).
PRIOR_IPOPT: dict[str, object] = {"max_soc": 0}

#: with the prior, each fitted body's second moments about its CoM (the diagonal entries of
#: its Cholesky factor V, Σ_c = V Vᵀ: the extent along z, along y beyond what z explains, along
#: x beyond both) stay within this factor of the model's either way (second moments: its
#: square). The prior's pull toward the model is weak where the data see little; without a
#: limit, a body's thinnest extent can walk off towards 0 (a collapse onto a plane, where the
#: FRF no longer depends on it and the fit wanders).
SHAPE_FACTOR = math.sqrt(10.0)


def shape_bounds(
    doc: UrdfDocument, layout: Layout, lbz: np.ndarray, ubz: np.ndarray
) -> list[tuple[str, int]]:
    """Tighten ``lbz``, ``ubz`` (in place) on the log-diagonal of every fitted body's ``V``
    to ``±ln SHAPE_FACTOR`` around the model's; returns the labels ``(name, z index)`` of the
    bounded entries, for the report of active bounds."""
    labels: list[tuple[str, int]] = []
    axes = ("x|yz", "y|z", "z")
    for blk in layout.blocks:
        if blk.fixed_v is not None:
            continue  # no inertia component free: V is fixed
        pi0 = pi_from_urdf(*link_inertial(doc, blk.link))
        if not is_feasible(pi0, blk.hull):
            pi0 = project_feasible(pi0, blk.hull, name=blk.link)
        th0 = theta_from_pi(pi0, name=blk.link)
        for k in range(3):
            i = blk.offset + 1 + k
            z0 = (th0[1 + k] + th0[0] - blk.shift[1 + k]) / blk.scale[1 + k]
            half = math.log(SHAPE_FACTOR) / blk.scale[1 + k]
            lbz[i], ubz[i] = max(lbz[i], z0 - half), min(ubz[i], z0 + half)
            labels.append((f"{blk.link} second moment along {axes[k]}", i))
    return labels


def prior_rows(
    nominal: UrdfDocument, width: float
) -> Callable[[FitProblem], NominalPrior | None] | None:
    """The ``extra_rows`` of a :class:`~bondid.optim.problem.FitProblem` with the prior toward
    ``nominal``'s values (None when ``width`` is 0): for each problem built from it, the
    :func:`shape_bounds` (tightening its ``lbz``/``ubz``, labels into ``var_labels``) and the
    rows of :func:`make_prior` over its decision vector (None, with a note, for a cost whose
    noise level is not known, e.g. the normalised-complex presolve and band steps)."""
    if not width > 0:
        return None

    def rows(p: FitProblem) -> NominalPrior | None:
        p.var_labels = p.var_labels + shape_bounds(nominal, p.layout, p.lbz, p.ubz)
        return make_prior(nominal, p.layout, p.frf, width, p.notes, n_z=p.size)

    return rows


def with_prior_ipopt(width: float, options: dict[str, Any] | None) -> dict[str, Any] | None:
    """IPOPT options with :data:`PRIOR_IPOPT` under ``options`` when the prior is on."""
    if not width > 0:
        return options
    return {**PRIOR_IPOPT, **(options or {})}

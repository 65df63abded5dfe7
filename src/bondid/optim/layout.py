"""The fit's decision vector: Cholesky-factor coordinates per body, scaled joint parameters.

Per fitted body the pseudo-inertia is written ``J = U Uᵀ`` with

    U = [[V, √m·t], [0, √m]],   V upper triangular (3×3), diag V = e^{δ},  m = e^{2α},

i.e. the log-Cholesky factor of :mod:`bondid.consistency.log_cholesky` in the coordinates
``ζ = (α, δ₁, δ₂, δ₃, σ₁₂, σ₂₃, σ₁₃, t₁, t₂, t₃)`` with ``δᵢ = α + dᵢ`` and ``σ = e^α s``. Every
ζ gives ``J ≻ 0`` (a physically consistent body), and the coordinates separate the URDF
quantities: ``m = e^{2α}``, ``c = t`` and the second moment about the CoM ``Σ_c = V Vᵀ`` (so
``I_c = tr(Σ_c) 𝟙 − Σ_c`` depends on δ and σ only). A fixed mass, CoM or full inertia is then a
fixed variable rather than a curved equality constraint, which keeps IPOPT's steps Newton-like.

Layout of the decision vector ``z`` (all entries O(1)):

* per body 10 entries ``z_b`` with ``ζ_b = shift_b + scale_b ∘ z_b``: δ shifted by ``ln √σ̄``
  (σ̄ the mean principal second moment at the start), σ scaled by ``√σ̄``, t scaled by the
  body length ``L`` (half the hull's bounding-box diagonal);
* for every free ``JOINT.stiffness`` / ``JOINT.damping``, one entry ``p / s`` with ``s`` the
  magnitude of its starting value (1 in SI units when that is 0);
* for every free transducer gain one entry ``ln(g / g₀)``, for every free point mix one entry
  ``(μ − μ₀) / s`` (``s`` = ``max(|μ₀|, 1)``: a mix may change sign), for every free mimic
  multiplier one entry ``(a − a₀) / s`` (likewise), for every free Rayleigh coefficient one
  entry ``α / s`` (``β / s``) (:mod:`.model_vars`).

Each body block and each joint, gain, mix or Rayleigh entry is a record of :mod:`.variables`.

:class:`Layout` is a *parameter model* for :class:`bondid.cost.FrfProblem` (``size``,
``values``, ``jacobian``); :mod:`bondid.optim.constraints` builds the NLP's constraint
expressions on it: equalities for fixed inertia components of a body whose other inertia
components are free, bounds on free inertia components, and the CoM-in-hull inequalities
``A t ≤ b`` (linear in z).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..consistency.hull import Hull
from ..consistency.log_cholesky import jacobian_pi_theta, pi_from_theta, theta_from_pi
from ..consistency.projection import is_feasible, project_feasible
from ..consistency.pseudo_inertia import pi_from_urdf, urdf_from_pi
from ..linear.affine import AffineModel
from ..model.document import UrdfDocument
from ..model.parameters import (
    COM_AXES,
    INERTIA_COMPONENTS,
    ParameterInfo,
    link_inertial,
    parameter_infos,
)
from .model_vars import ModelVars
from .variables import (
    _ALPHA,
    _IJ,
    _T,
    BodyBlock,
    GainVar,
    JointVar,
    MixVar,
    RayleighVar,
    named_from_pi,
)


def _new_block(doc: UrdfDocument, affine: AffineModel, link: str, hull: Hull | None) -> BodyBlock:
    """A body's block with its length scale ``L``: half the hull's bounding-box diagonal, else
    the radius of gyration, else 0.1 m (the δ shift and σ scale are set by ``start``)."""
    m, _, I_c = link_inertial(doc, link)
    if hull is not None:
        length = 0.5 * hull.size
    elif m > 0:
        length = float(np.sqrt(max(np.trace(I_c), 0.0) / m)) or 0.1
    else:
        length = 0.1
    scale = np.ones(10)
    scale[7:] = length
    return BodyBlock(link, affine.bodies.index(link), 0, np.zeros(10), scale, length, 1.0, hull)


class Layout(ModelVars):
    """Decision vector of the fit (see the module docstring) and its maps.

    Args:
        doc: the model (values of the parameters that are not free).
        affine: any :class:`AffineModel` of ``doc`` (gives body and DOF indices, base values).
        infos: the free parameters, in order (length ``n``).
        hulls: link hull per fitted body (None = no CoM constraint).
        ties: ``{leader: [(member, factor), ...]}``: parameters set to ``factor · leader``
            (:mod:`bondid.optim.tied`). A tied joint parameter shares its leader's entry of
            ``z``; a tied inertial component gets its body's block (its body stays physically
            consistent by construction) and an equality constraint to its leader's value.
    """

    def __init__(
        self,
        doc: UrdfDocument,
        affine: AffineModel,
        infos: Sequence[ParameterInfo],
        hulls: dict[str, Hull | None],
        ties: dict[str, list[tuple[str, float]]] | None = None,
    ):
        """Body blocks first (10 entries each), then gains and joint parameters."""
        self.infos = list(infos)
        self.base_pi = affine.pi.copy()
        self.base_k = affine.stiffness.copy()
        self.base_d = affine.damping.copy()
        ties = ties or {}
        index = {info.name: j for j, info in enumerate(self.infos)}
        inertial = {k: v for k, v in ties.items() if self.infos[index[k]].is_inertial}
        self.blocks = self._body_blocks(doc, affine, hulls, index, inertial)
        self.joints: list[JointVar] = []
        self.gains: list[GainVar] = []
        self.mixes: list[MixVar] = []
        self.couplings: list[MixVar] = []
        self.rayleigh: list[RayleighVar] = []
        self.notes: list[str] = []
        offset = 10 * len(self.blocks)
        for j, info in enumerate(self.infos):
            if info.kind == "gain":
                self.gains.append(GainVar(info.name, offset, j))
            elif info.kind == "mix":
                self.mixes.append(MixVar(info.name, info.owner, offset, j))
            elif info.kind == "multiplier":
                self.couplings.append(MixVar(info.name, info.owner, offset, j))
            elif info.kind == "rayleigh":
                self.rayleigh.append(RayleighVar(info.name, str(info.component), offset, j))
            elif not info.is_inertial:
                dof = affine.dofs.index(info.owner)
                self.joints.append(JointVar(info.name, info.kind, dof, offset, j, 1.0))
            else:
                continue
            offset += 1
        self.size = offset
        self._tie_members(affine, {k: v for k, v in ties.items() if k not in inertial})
        self._model_vars_of(affine)

    def _body_blocks(
        self,
        doc: UrdfDocument,
        affine: AffineModel,
        hulls: dict[str, Hull | None],
        index: dict[str, int],
        ties: dict[str, list[tuple[str, float]]],
    ) -> list[BodyBlock]:
        """One :class:`BodyBlock` per link with a free or tied inertial parameter, in order
        (``index``: each free name's position; ``ties``: the inertial ones)."""
        blocks: dict[str, BodyBlock] = {}

        def block(link: str) -> BodyBlock:
            if link not in blocks:
                blocks[link] = _new_block(doc, affine, link, hulls.get(link))
                blocks[link].offset = 10 * (len(blocks) - 1)
            return blocks[link]

        for j, info in enumerate(self.infos):
            if info.is_inertial:
                block(info.owner).free[info.component_key] = j
        all_infos = {p.name: p for p in parameter_infos(doc)}
        for leader, members in ties.items():
            for member, factor in members:
                info = all_infos[member]
                block(info.owner).tied[info.component_key] = (index[leader], factor)
        for blk in blocks.values():
            m, c, I_c = link_inertial(doc, blk.link)
            urdf = {"mass": m}
            urdf.update({f"com.{a}": float(c[k]) for k, a in enumerate(COM_AXES)})
            urdf.update({f"inertia.{n}": float(I_c[_IJ[n]]) for n in INERTIA_COMPONENTS})
            blk.fixed = {k: v for k, v in urdf.items() if k not in blk.free and k not in blk.tied}
        return list(blocks.values())

    def _tie_members(self, affine: AffineModel, ties: dict[str, list[tuple[str, float]]]) -> None:
        """A :class:`JointVar` per tied member, on its leader's entry of ``z``."""
        leaders = {jv.name: k for k, jv in enumerate(self.joints)}
        for lead, members in ties.items():
            k = leaders[lead]
            for member, factor in members:
                joint, _, kind = member.rpartition(".")
                dof = affine.dofs.index(joint)
                index = self.joints[k].index
                self.joints.append(JointVar(member, kind, dof, index, -1, 1.0, factor, k))

    # -- start point -----------------------------------------------------------------------
    def start(
        self, doc: UrdfDocument, p0: np.ndarray, lower: np.ndarray, upper: np.ndarray
    ) -> np.ndarray:
        """Decision vector ``z`` (size,) for named values ``p0`` (n,), projected if needed.

        Bodies whose start is not physically consistent or whose CoM lies outside the hull are
        projected (:func:`bondid.consistency.project_feasible`); a note says so. Also fixes the
        joint scales and the inertia-constraint scales.
        """
        z = np.zeros(self.size)
        for blk in self.blocks:
            m, c, I_c = link_inertial(doc, blk.link)
            starts = {comp: float(p0[j]) for comp, j in blk.free.items()}
            # a tied member starts at its leader's start (a random start moves both)
            starts.update({comp: f * float(p0[j]) for comp, (j, f) in blk.tied.items()})
            for comp, v in starts.items():
                if comp == "mass":
                    m = v
                elif comp.startswith("com."):
                    c[COM_AXES.index(comp[4:])] = v
                else:
                    r, s = _IJ[comp[8:]]
                    I_c[r, s] = I_c[s, r] = v
            pi = pi_from_urdf(m, c, I_c)
            if not is_feasible(pi, blk.hull):
                pi = project_feasible(pi, blk.hull, name=blk.link)
                moved = {k: v for k, v in named_from_pi(pi).items() if k != "mass"}
                self.notes.append(
                    f"{blk.link}: start not feasible (pseudo-inertia or CoM outside the hull);"
                    " projected to " + ", ".join(f"{k}={v:.6g}" for k, v in moved.items())
                )
            _, _, I_p = urdf_from_pi(pi)
            blk.inertia_scale = float(np.trace(I_p)) / 3.0
            sigma_bar = float(np.trace(I_p)) / 6.0  # mean principal second moment about CoM
            blk.shift[1:4] = 0.5 * np.log(sigma_bar)
            blk.scale[4:7] = np.sqrt(sigma_bar)
            theta = theta_from_pi(pi, name=blk.link)
            zeta = theta.copy()
            zeta[1:4] = theta[1:4] + theta[0]
            zeta[4:7] = theta[4:7] * np.exp(theta[0])
            z[blk.offset : blk.offset + 10] = (zeta - blk.shift) / blk.scale
            if not any(k.startswith("inertia.") for k in [*blk.free, *blk.tied]):
                blk.fixed_v = z[blk.offset + 1 : blk.offset + 7].copy()
        for jv in self.joints:
            if jv.leader >= 0:
                jv.scale = jv.factor * self.joints[jv.leader].scale
                continue
            v = float(p0[jv.name_index])
            # a start at 0 keeps the SI unit as its scale: IPOPT pushes a start off its bound
            # by ~1e-2 scaled units, which, scaled by the (finite, far) upper bound, would be a
            # stiff spring on the joint (measured: the bundled --free all fit then stalls)
            jv.scale = abs(v) if v != 0 else 1.0
            z[jv.index] = v / jv.scale
        self._start_model_vars(p0, z)
        return z

    # -- parameter-model protocol (numpy) ------------------------------------------------
    def values(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(π ``(nb, 10)``, stiffness ``(nv,)``, damping ``(nv,)``) at ``z``."""
        z = np.asarray(z, dtype=float)
        pi = self.base_pi.copy()
        for blk in self.blocks:
            pi[blk.body] = pi_from_theta(blk.theta(z))
        k, d = self.base_k.copy(), self.base_d.copy()
        for jv in self.joints:
            (k if jv.kind == "stiffness" else d)[jv.dof] = jv.scale * z[jv.index]
        return pi, k, d

    def jacobian(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """dπ/dz ``(nb, 10, size)``, dk/dz ``(nv, size)``, dd/dz ``(nv, size)``."""
        z = np.asarray(z, dtype=float)
        dpi = np.zeros((self.base_pi.shape[0], 10, self.size))
        dk = np.zeros((self.base_k.size, self.size))
        dd = np.zeros((self.base_d.size, self.size))
        for blk in self.blocks:
            dpi[blk.body, :, blk.offset : blk.offset + 10] = jacobian_pi_theta(
                blk.theta(z)
            ) @ blk.dtheta_dz(z)
        for jv in self.joints:
            (dk if jv.kind == "stiffness" else dd)[jv.dof, jv.index] = jv.scale
        return dpi, dk, dd

    # -- named values ------------------------------------------------------------------------
    def body_values(self, z: np.ndarray) -> dict[str, dict[str, float]]:
        """URDF-form values of every fitted body at ``z``: ``{link: {component: value}}``."""
        return {b.link: named_from_pi(pi_from_theta(b.theta(z))) for b in self.blocks}

    def named(self, z: np.ndarray) -> np.ndarray:
        """Values ``(n,)`` of the free named parameters at ``z`` (SI units)."""
        out = np.empty(len(self.infos))
        for blk in self.blocks:
            vals = named_from_pi(pi_from_theta(blk.theta(z)))
            for comp, j in blk.free.items():
                out[j] = vals[comp]
        for jv in self.joints:
            if jv.name_index >= 0:
                out[jv.name_index] = jv.scale * z[jv.index]
        self._named_model_vars(z, out)
        return out

    # -- variable bounds -------------------------------------------------------------------
    def variable_bounds(
        self, lower: np.ndarray, upper: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, list[tuple[str, int]]]:
        """Bounds on ``z`` ``(size,)`` x2 and labels ``(parameter name, z index)`` of bounded
        entries that stand for a named parameter (mass via α, CoM via t, joint parameters)."""
        lbz = np.full(self.size, -np.inf)
        ubz = np.full(self.size, np.inf)
        labels: list[tuple[str, int]] = []
        for blk in self.blocks:
            ia = blk.offset + _ALPHA
            if "mass" in blk.free:
                j = blk.free["mass"]
                lo, hi = float(lower[j]), float(upper[j])
                lbz[ia] = 0.5 * np.log(lo) if lo > 0 else -np.inf
                ubz[ia] = 0.5 * np.log(hi) if np.isfinite(hi) else np.inf
                labels.append((self.infos[j].name, ia))
            elif "mass" not in blk.tied:  # a tied mass: held by its tie's equality
                lbz[ia] = ubz[ia] = 0.5 * np.log(blk.fixed["mass"])
            for k, a in enumerate(COM_AXES):
                it = blk.offset + _T + k
                comp = f"com.{a}"
                if comp in blk.free:
                    j = blk.free[comp]
                    lbz[it] = (lower[j] - blk.shift[_T + k]) / blk.scale[_T + k]
                    ubz[it] = (upper[j] - blk.shift[_T + k]) / blk.scale[_T + k]
                    labels.append((self.infos[j].name, it))
                elif comp not in blk.tied:
                    lbz[it] = ubz[it] = blk.fixed[comp] / blk.scale[_T + k]
            if blk.fixed_v is not None:
                sl = slice(blk.offset + 1, blk.offset + 7)
                lbz[sl] = ubz[sl] = blk.fixed_v
        for jv in (j for j in self.joints if j.name_index >= 0):
            lbz[jv.index] = lower[jv.name_index] / jv.scale
            ubz[jv.index] = upper[jv.name_index] / jv.scale
            labels.append((jv.name, jv.index))
        labels += self._bound_model_vars(lower, upper, lbz, ubz)
        return lbz, ubz, labels

"""The augmented model of a refit: the model, the effects already accepted, one candidate.

A diagnosis adds effects one at a time (:mod:`.search`): the candidates of a later step are
tried on top of the effects accepted before, whose parameters stay free in every refit.
:func:`build` turns a model text, the nominal refit variables, the accepted effects and an
optional candidate into a refit over the optimisation core (:class:`~.refit.Refit`): the
augmented document (structural effects built in, unless the model already has them), the
parameters (nominal first, then the new ones in the order accepted…, candidate: tied URDF
parameters or the modifier's) and one FRF modifier that multiplies the factors of every
modifier effect among them and composes their mixings (:class:`ComposedModifier`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..cost.modifier import Mixing
from ..data.measurement import FrfData
from ..model.document import UrdfDocument
from ..model.parameters import parameter_infos, set_parameter
from .effects import Candidate, get_effect
from .effects.base import NewParameter
from .refit import NewVar, Nominal, Refit

_TIEABLE = ("stiffness", "damping")


class ComposedModifier:
    """Product of the FRF factors of several modifier candidates, and their mixings.

    ``values`` ``(n_θ,)`` are the candidates' parameters one after the other (in the order
    given); a call returns ``G`` ``(n_out, n_in, n_f)`` and ``dG/dθ`` ``(n_out, n_in, n_f,
    n_θ)``; :meth:`mixing` the product of the candidates' output and input mixings (the
    first candidate's applied first: ``L = L_k ⋯ L_1``, ``R = R_1 ⋯ R_k``) with their
    derivatives, when any candidate mixes (:attr:`mixes`).
    """

    def __init__(self, candidates: Sequence[Candidate]):
        self.parts = [(get_effect(c.effect), c) for c in candidates]
        self.sizes = [len(c.parameters) for c in candidates]
        #: does any candidate mix outputs or inputs (:meth:`mixing`)?
        self.mixes = any(e.mixes for e, _ in self.parts)

    def mixing(
        self, values: np.ndarray, outputs: tuple[str, ...], inputs: tuple[str, ...]
    ) -> Mixing | None:
        """The composed :class:`~bondid.cost.modifier.Mixing` at ``values`` (None: no part
        mixes)."""
        n_theta = int(sum(self.sizes))
        mats: dict[str, tuple[np.ndarray, np.ndarray] | None] = {"left": None, "right": None}
        k = 0
        for (effect, cand), n in zip(self.parts, self.sizes, strict=True):
            m = effect.mixing(cand, values[k : k + n], outputs, inputs) if effect.mixes else None
            if m is not None:
                for side, M, dM, size in (("left", m.left, m.dleft, len(outputs)),
                                          ("right", m.right, m.dright, len(inputs))):  # fmt: skip
                    if M is None:
                        continue
                    d = np.zeros((size, size, n_theta), complex)
                    if dM is not None:
                        d[..., k : k + n] = dM
                    mats[side] = _chained(mats[side], (np.asarray(M, complex), d), side)
            k += n
        left, right = mats["left"], mats["right"]
        if left is None and right is None:
            return None
        return Mixing(
            None if left is None else left[0], None if left is None else left[1],
            None if right is None else right[0], None if right is None else right[1],
        )  # fmt: skip

    def __call__(
        self, values: np.ndarray, freq_hz: np.ndarray, outputs: tuple[str, ...],
        inputs: tuple[str, ...],
    ) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        shape = (len(outputs), len(inputs), np.size(freq_hz))
        G = np.ones(shape, complex)
        factors, derivs = [], []
        k = 0
        for (effect, cand), n in zip(self.parts, self.sizes, strict=True):
            g, dg = effect.modifier(cand, values[k : k + n], freq_hz, outputs, inputs)
            factors.append(g)
            derivs.append(dg)
            G = G * g
            k += n
        dG = np.zeros((*shape, k), complex)
        k = 0
        for j, dg in enumerate(derivs):
            others = np.ones(shape, complex)
            for i, h in enumerate(factors):
                if i != j:
                    others = others * h
            dG[..., k : k + dg.shape[-1]] = dg * others[..., None]
            k += dg.shape[-1]
        return G, dG


def _chained(
    acc: tuple[np.ndarray, np.ndarray] | None, new: tuple[np.ndarray, np.ndarray], side: str
) -> tuple[np.ndarray, np.ndarray]:
    """``(M, ∂M/∂θ)`` of the product of the mixing so far ``acc`` and a later one ``new``:
    ``M_new · M_acc`` on the output side (``left``), ``M_acc · M_new`` on the input side."""
    if acc is None:
        return new
    (A, dA), (B, dB) = acc, new
    if side == "left":
        return B @ A, np.einsum("abk,bc->ack", dB, A) + np.einsum("ab,bck->ack", B, dA)
    return A @ B, np.einsum("abk,bc->ack", dA, B) + np.einsum("ab,bck->ack", A, dB)


@dataclass
class Augmented:
    """One augmented model ready to refit (see :func:`build`)."""

    doc: UrdfDocument
    refit: Refit
    modifier: ComposedModifier | None
    n_nominal: int
    n_accepted: int

    @property
    def names(self) -> list[str]:
        """Readable names: the nominal parameters, then every new one."""
        return [*self.refit.nominal.names, *(v.name for v in self.refit.new)]


def with_values(cand: Candidate, values: Sequence[float] | np.ndarray) -> Candidate:
    """``cand`` with its parameters starting at ``values`` (clipped to their bounds)."""
    pars = tuple(
        replace(p, initial=float(np.clip(v, p.lower, p.upper)))
        for p, v in zip(cand.parameters, values, strict=True)
    )
    return replace(cand, parameters=pars, variants=())


def chain_of(
    accepted: Sequence[Candidate], cand: Candidate | None, new_values: np.ndarray
) -> tuple[Candidate, ...]:
    """``accepted`` and ``cand`` (when given) with their fitted ``new_values`` (SI, in order)."""
    out: list[Candidate] = []
    k = 0
    for c in [*accepted, *([cand] if cand is not None else [])]:
        n = len(c.parameters)
        out.append(with_values(c, new_values[k : k + n]))
        k += n
    return tuple(out)


def _has_members(doc: UrdfDocument, cand: Candidate) -> bool:
    names = {p.name for p in parameter_infos(doc)}
    return all(m in names for p in cand.parameters for m, _ in p.members)


def new_var(
    p: NewParameter, kinds: dict[str, str], theta: int | None, taken: Sequence[str] = ()
) -> NewVar:
    """The refit's view of a candidate parameter: a modifier's ``theta``, else its first
    member as the leader and the others tied (held when it ties members that are not a
    joint stiffness/damping, which the core cannot tie; a single member of any kind, e.g. a
    link mass, is free; held too when its leader is already a refitted name in ``taken``)."""
    if theta is not None or not p.members:
        return NewVar(p.name, p.initial, p.lower, p.upper, theta=theta, linear=p.signed,
                      scale=p.typical)  # fmt: skip
    (lead, f0), rest = p.members[0], p.members[1:]
    held = lead in taken or (bool(rest) and any(kinds.get(m) not in _TIEABLE for m, _ in p.members))
    ties = tuple((m, f / f0) for m, f in rest)
    return NewVar(p.name, p.initial, p.lower, p.upper, lead, f0, ties, held=held)


def recentred(
    nominal: Nominal, doc: UrdfDocument, links: Sequence[str], data: Sequence[FrfData]
) -> Nominal:
    """``nominal`` with the inertial parameters of ``links`` taken at their values in the
    augmented model ``doc`` (centre of the prior) with ``bondid.fit``'s default bounds around
    them (data's highest frequency): a structural effect that replaces a link's inertial (a
    link cut in two keeps its name for one part, :mod:`.effects.flexible_link`) changes what
    those parameters mean, and the nominal model's values no longer apply."""
    from ..model.parameters import get_parameters
    from ..optim.bounds import default_bounds

    infos = {p.name: p for p in parameter_infos(doc)}
    idx = [i for i, n in enumerate(nominal.names)
           if n in infos and infos[n].is_inertial and infos[n].owner in links]  # fmt: skip
    if not idx:
        return nominal
    names = [nominal.names[i] for i in idx]
    f_max = max(float(np.max(d.freq_hz)) for d in data) if data else None
    lo, hi = default_bounds(doc, names, f_max_hz=f_max)
    lower, upper, centre = nominal.lower.copy(), nominal.upper.copy(), nominal.centre.copy()
    lower[idx], upper[idx], centre[idx] = lo, hi, get_parameters(doc, names)
    return replace(nominal, lower=lower, upper=upper, centre=centre)


def build(
    urdf: str,
    nominal: Nominal,
    data: Sequence[FrfData],
    options: object,
    accepted: Sequence[Candidate] = (),
    candidate: Candidate | None = None,
    ipopt: dict | None = None,
) -> Augmented:
    """The augmented model (module docstring) with its refit on ``data``.

    Args:
        urdf: model text; structural effects of ``accepted`` it lacks are built in (at
            their parameters' initial values; the candidate always).
        nominal: the nominal parameters (:class:`~.refit.Nominal`).
        data: data sets of the refit (receptance).
        options: :class:`bondid.cost.problem.CostOptions`.
        accepted: effects accepted before (parameters starting at their fitted values).
        candidate: the effect tried now, or None.
        ipopt: IPOPT options of the refit's solves (:class:`~.refit.Refit`).
    """
    doc = UrdfDocument.from_string(urdf, source="refit model")
    chain = [*accepted, *([candidate] if candidate is not None else [])]
    for cand in chain:
        effect = get_effect(cand.effect)
        if not effect.is_modifier and (candidate is cand or not _has_members(doc, cand)):
            doc = effect.augment(doc, cand)
        elif not effect.is_modifier:
            for p in cand.parameters:  # accepted and already built in: start at its values
                for m, fac in p.members:
                    set_parameter(doc, m, fac * p.initial)
    split = sorted({str(k) for c in chain for k in c.spec.get("replaces_inertial", ())})
    if split:
        nominal = recentred(nominal, doc, split, data)
    kinds = {p.name: p.kind for p in parameter_infos(doc)}
    new: list[NewVar] = []
    mods: list[Candidate] = []
    n_theta = 0
    for cand in chain:
        is_mod = get_effect(cand.effect).is_modifier
        for i, p in enumerate(cand.parameters):
            new.append(new_var(p, kinds, n_theta + i if is_mod else None, nominal.names))
        if is_mod:
            mods.append(cand)
            n_theta += len(cand.parameters)
    n_acc = sum(len(c.parameters) for c in accepted)
    modifier = ComposedModifier(mods) if mods else None
    n_own = 0 if candidate is None else len(candidate.parameters)
    refit = Refit(doc, data, nominal, new, modifier, options, n_own, ipopt)  # type: ignore[arg-type]
    return Augmented(doc, refit, modifier, len(nominal.names), n_acc)

"""The augmented model of a refit: the model, the effects already accepted, one candidate.

A diagnosis adds effects one at a time (:mod:`.search`): the candidates of a later step are
tried on top of the effects accepted before, whose parameters stay free in every refit.
:func:`build` turns a model text, the nominal refit variables, the accepted effects and an
optional candidate into a refit over the optimisation core (:class:`~.refit.Refit`): the
augmented document (structural effects built in, unless the model already has them), the
parameters (nominal first, then the new ones in the order accepted…, candidate: tied URDF
parameters or the modifier's) and one FRF modifier that multiplies the factors of every
modifier effect among them (:class:`ComposedModifier`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..data.measurement import FrfData
from ..model.document import UrdfDocument
from ..model.parameters import parameter_infos, set_parameter
from .effects import Candidate, get_effect
from .effects.base import NewParameter
from .refit import NewVar, Nominal, Refit

_TIEABLE = ("stiffness", "damping")


class ComposedModifier:
    """Product of the FRF factors of several modifier candidates.

    ``values`` ``(n_θ,)`` are the candidates' parameters one after the other (in the order
    given); returns ``G`` ``(n_out, n_in, n_f)`` and ``dG/dθ`` ``(n_out, n_in, n_f, n_θ)``.
    """

    def __init__(self, candidates: Sequence[Candidate]):
        self.parts = [(get_effect(c.effect), c) for c in candidates]
        self.sizes = [len(c.parameters) for c in candidates]

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
        return NewVar(p.name, p.initial, p.lower, p.upper, theta=theta)
    (lead, f0), rest = p.members[0], p.members[1:]
    held = lead in taken or (bool(rest) and any(kinds.get(m) not in _TIEABLE for m, _ in p.members))
    ties = tuple((m, f / f0) for m, f in rest)
    return NewVar(p.name, p.initial, p.lower, p.upper, lead, f0, ties, held=held)


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

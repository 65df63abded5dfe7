"""The augmented model of a refit: the model, the effects already accepted, one candidate.

A diagnosis adds effects one at a time (:mod:`.search`): the candidates of a later step are
tried on top of the effects accepted before, whose parameters stay free in every refit.
:func:`build` turns a model text, the nominal refit variables, the accepted effects and an
optional candidate into what the engine needs: the augmented document (structural effects
built in, unless the model already has them), the variables (nominal first, then the new
parameters in the order accepted…, candidate) and one FRF modifier that multiplies the
factors of every modifier effect among them (:class:`ComposedModifier`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..data.measurement import FrfData
from ..model.document import UrdfDocument
from ..model.parameters import parameter_infos
from .effects import Candidate, get_effect
from .engine import Refit
from .variables import Variable


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
    variables: list[Variable]
    refit: Refit
    modifier: ComposedModifier | None
    n_nominal: int
    n_accepted: int


def with_values(cand: Candidate, values: Sequence[float] | np.ndarray) -> Candidate:
    """``cand`` with its parameters starting at ``values`` (clipped to their bounds)."""
    pars = tuple(
        replace(p, initial=float(np.clip(v, p.lower, p.upper)))
        for p, v in zip(cand.parameters, values, strict=True)
    )
    return replace(cand, parameters=pars, variants=())


def _has_members(doc: UrdfDocument, cand: Candidate) -> bool:
    names = {p.name for p in parameter_infos(doc)}
    return all(m in names for p in cand.parameters for m, _ in p.members)


def build(
    urdf: str,
    nominal: Sequence[Variable],
    data: Sequence[FrfData],
    options: object,
    accepted: Sequence[Candidate] = (),
    candidate: Candidate | None = None,
) -> Augmented:
    """The augmented model (module docstring) with its refit on ``data``.

    Args:
        urdf: model text; structural effects of ``accepted`` it lacks are built in.
        nominal: refit variables of the nominal parameters (values of ``urdf``).
        data: data sets of the refit (receptance).
        options: :class:`bondid.cost.problem.CostOptions`.
        accepted: effects accepted before (parameters starting at their fitted values).
        candidate: the effect tried now, or None.
    """
    doc = UrdfDocument.from_string(urdf, source="refit model")
    variables = list(nominal)
    mods: list[Candidate] = []
    n_acc = 0
    for k, cand in enumerate([*accepted, *([candidate] if candidate is not None else [])]):
        effect = get_effect(cand.effect)
        if not effect.is_modifier and (candidate is cand or not _has_members(doc, cand)):
            doc = effect.augment(doc, cand)
        offset = sum(len(m.parameters) for m in mods)
        for i, p in enumerate(cand.parameters):
            mod = offset + i if effect.is_modifier else None
            variables.append(
                Variable(f"{p.name}", p.initial, p.lower, p.upper, p.members, mod, p.unit)
            )
        if effect.is_modifier:
            mods.append(cand)
        if k < len(accepted):
            n_acc += len(cand.parameters)
    modifier = ComposedModifier(mods) if mods else None
    refit = Refit(doc, data, variables, modifier=modifier, options=options)  # type: ignore[arg-type]
    return Augmented(doc, variables, refit, modifier, len(nominal), n_acc)

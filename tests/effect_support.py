"""Shared steps of the effect tests (tests/test_effect_*.py): noisy data of a truth, a
candidate's refit from a perturbed start, and the finite-difference check of its gradient."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from bondid.cost.problem import CostOptions
from bondid.data.noise import add_measurement_noise
from bondid.model import UrdfDocument
from bondid.simulate import log_grid, simulate

#: 0.5 % relative noise (and a floor 70 dB under each sensor's response): the data's noise
NOISE = 0.005
#: the refit problem's exact gradient against central differences of step 1e-6 in ``z``
#: (relative to its largest entry): truncation and rounding stay near 1e-5
GRAD_TOL = 1e-4


def noisy_data(
    truth: UrdfDocument, ops: Sequence[dict], n: int = 150, seed: int = 0,
    transform: Callable[[np.ndarray, np.ndarray, tuple, tuple], np.ndarray] | None = None,
) -> list:  # fmt: skip
    """Data of ``truth`` at ``ops`` on ``n`` lines, 1 Hz – 4 kHz: exact FRFs, then
    ``transform(H, f, outputs, inputs)`` (a signal effect), then :data:`NOISE`."""
    f = log_grid(1.0, 4000.0, n)
    out = []
    for k, op in enumerate(ops):
        d = simulate(truth, op, f)
        if transform is not None:
            d.H = transform(d.H, f, tuple(d.outputs), tuple(d.inputs))
        d.H, d.coherence = add_measurement_noise(
            d.H, f, rel=NOISE, floor_db=-70, rng=seed + k, floor_ref="response"
        )
        out.append(d)
    return out


def refit_of(doc: UrdfDocument, names: Sequence[str], data: list, cand):
    """The diagnosis's refit of ``cand`` on ``doc`` (nominal ``names`` free, prior as a
    diagnosis has it)."""
    from bondid.diagnose.augmented import build
    from bondid.diagnose.refit import nominal_space

    space = nominal_space(doc, list(names), 4000.0)
    return build(doc.to_string(), space, data, CostOptions(), (), cand).refit


def mixed_refit(doc: UrdfDocument, names: Sequence[str], ops: Sequence[dict], effect, cand,
                values: np.ndarray):  # fmt: skip
    """The refit of the mixing candidate ``cand`` from no mixing, on noisy data of ``doc``
    with the y stage 5 % lighter and ``effect``'s mixing at ``values`` applied."""
    from bondid.model import get_parameter, set_parameter

    truth = doc.copy()
    set_parameter(truth, "y_stage.mass", 0.95 * get_parameter(doc, "y_stage.mass"))

    def mix(H, f, outs, ins):
        return effect.mixing(cand, values, outs, ins).apply(H)

    return refit_of(doc, names, noisy_data(truth, ops, transform=mix), cand)


def solve(refit, max_iter: int = 150) -> np.ndarray:
    """The candidate's new parameters (SI) after one direct solve from the refit's start."""
    from bondid.optim.schedules import direct

    state, _, _ = refit.solve(refit.state0, direct(), max_iter=max_iter)
    return refit.new_values(state)


def gradient_error(refit, shift: float = 0.05) -> float:
    """Largest error of the refit problem's exact gradient against central differences at
    ``z0 + shift``, relative to the gradient's largest entry, over the entries that can
    move (the fixed ones' gradient is 0 by construction: IPOPT never moves them)."""
    p = refit.problem
    nlp = p.nlp()
    z = np.clip(p.z0 + shift, p.lbz, p.ubz)
    g = nlp.gradient(z)
    h = 1e-6
    fd = np.array([(nlp.cost(z + e) - nlp.cost(z - e)) / (2 * h) for e in h * np.eye(z.size)])
    fixed = p.lbz == p.ubz
    assert np.all(g[fixed] == 0.0)
    return float(np.max(np.abs(g - fd)[~fixed]) / np.max(np.abs(g)))


def modifier_fd_error(effect, cand, values: np.ndarray, f, outputs, inputs) -> float:
    """Largest error of ``effect``'s ``∂G/∂θ`` (and of its mixing's ``∂L/∂θ``, ``∂R/∂θ``)
    against central differences, relative to the largest derivative."""
    _, dG = effect.modifier(cand, values, f, outputs, inputs)
    m = effect.mixing(cand, values, outputs, inputs)
    errs, scale = [], [float(np.max(np.abs(dG))) if dG.size else 0.0]
    for k in range(values.size):
        h = 1e-6 * max(abs(float(values[k])), 1.0 if cand.parameters[k].signed else 0.0)
        vp, vm = values.copy(), values.copy()
        vp[k] += h
        vm[k] -= h
        fd = (effect.modifier(cand, vp, f, outputs, inputs)[0]
              - effect.modifier(cand, vm, f, outputs, inputs)[0]) / (2 * h)  # fmt: skip
        errs.append(float(np.max(np.abs(fd - dG[..., k]))))
        if m is not None:
            mp, mm = (
                effect.mixing(cand, vp, outputs, inputs),
                effect.mixing(cand, vm, outputs, inputs),
            )
            for side in ("left", "right"):
                M, dM = getattr(m, side), getattr(m, "d" + side)
                if M is None:
                    continue
                fdM = (getattr(mp, side) - getattr(mm, side)) / (2 * h)
                errs.append(float(np.max(np.abs(fdM - dM[..., k]))))
                scale.append(float(np.max(np.abs(dM))))
    return max(errs) / max(scale)

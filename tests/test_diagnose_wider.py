"""Known answers for the wider search of a candidate's refit that ends above the noise level
(:func:`bondid.diagnose.alternatives.wider_search`): the refit's own scans when the
screening's start put the new mode out of the band, the band continuation from the nominal
model, and the rescue without its own continuation after it."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from models import noisy_bonder_data

from bondid.model import UrdfDocument

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "urdf" / "bonder.urdf"
FEW = ["x_stage.mass", "y_stage.mass", "z_stage.mass", "x_guide_ry.stiffness"]
#: a refit "at the truth": its training objective within this factor of the exact model's
AT_TRUTH = 1.3


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(MODEL)


_data = noisy_bonder_data


@pytest.fixture(scope="module")
def compliance(doc):  # type: ignore[no-untyped-def]
    """A translational compliance under the x stage at 1300 Hz: the candidate, its exact new
    parameters and the data of the nominal model with it."""
    from bondid.diagnose.augmented import with_values
    from bondid.diagnose.effects import get_effect

    e = get_effect("joint_compliance")
    c = next(c for c in e.candidates(doc) if c.location == "base->x_stage:tz")
    c = replace(c, variants=())
    exact = np.array([p.initial * (1300.0 / 300.0) ** (2 * p.scan) for p in c.parameters])
    return c, exact, _data(e.augment(doc, with_values(c, exact)))


def _job(doc, c, data, start):  # type: ignore[no-untyped-def]
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.refit import nominal_space
    from bondid.diagnose.runner import Job

    text = doc.to_string()
    space = nominal_space(doc, FEW, 4000.0)
    return Job(text, space, data, data, data, c, CostOptions(), alt_urdf=text,
               start_new=tuple(start))  # fmt: skip


def _exact_cost(doc, c, data, exact) -> float:  # type: ignore[no-untyped-def]
    from bondid.cost.problem import CostOptions
    from bondid.diagnose.augmented import build
    from bondid.diagnose.refit import nominal_space

    r = build(doc.to_string(), nominal_space(doc, FEW, 4000.0), data, CostOptions(), (),
              c).refit  # fmt: skip
    return r.cost(r.with_new(r.state0, exact))


def test_own_scans_recover_a_mode_the_screening_start_put_out_of_the_band(doc, compliance):
    """Known answer: started with the joint's mode at ~8 kHz (twice the band's top, the
    damping 1000x too low), the refit ends above the noise level; the refit with its own scans
    (the screening's start dropped) ends within AT_TRUTH of the exact model's objective."""
    from bondid.diagnose.alternatives import with_own_scans
    from bondid.diagnose.rescue import above_noise
    from bondid.diagnose.runner import _fit

    c, exact, data = compliance
    job = _job(doc, c, data, exact * np.array([40.0, 1e-3]))
    aug, state, res = _fit(job)
    assert above_noise(aug.refit, state)
    aug2, state2, _, note = with_own_scans(job, aug, state, res)
    c_exact = _exact_cost(doc, c, data, exact)
    assert aug2.refit.cost(state2) < AT_TRUTH * c_exact, (aug2.refit.cost(state2), c_exact)
    assert note.startswith("own scans") and note.endswith(", kept")


def test_without_a_screening_start_own_scans_do_nothing(doc, compliance):
    """The job already ran its own scans: nothing to redo (same state, no note)."""
    from bondid.diagnose.alternatives import with_own_scans
    from bondid.diagnose.runner import _fit

    c, exact, data = compliance
    job = replace(_job(doc, c, data, exact), start_new=())
    aug, state, res = _fit(job)
    aug2, state2, _, note = with_own_scans(job, aug, state, res)
    assert note == "" and aug2 is aug and state2 is state


def test_continuation_from_the_nominal_model_is_kept_only_when_lower(doc, compliance):
    """From a model whose stage masses are bent 40 %, the refit reaches the exact model's
    objective (the problem is small); the band continuation from the nominal model ends
    higher here (its band steps pull away from an exact start: 2.0x the noise level against
    1.5x) and is not kept: the refit is returned unchanged."""
    from bondid.diagnose.alternatives import continuation_from_nominal
    from bondid.diagnose.runner import _fit
    from bondid.model.parameters import get_parameter, set_parameter

    c, exact, data = compliance
    bent = doc.copy()
    for name, f in zip(FEW[:3], (1.4, 0.6, 1.4), strict=True):
        set_parameter(bent, name, get_parameter(doc, name) * f)
    job = replace(_job(doc, c, data, exact), alt_urdf=None, urdf=bent.to_string())
    aug, state, res = _fit(job)
    c_exact = _exact_cost(doc, c, data, exact)
    assert aug.refit.cost(state) < AT_TRUTH * c_exact
    aug2, state2, _, note = continuation_from_nominal(
        replace(job, alt_urdf=doc.to_string()), aug, state, res
    )
    assert aug2 is aug and state2 is state, note
    assert note.startswith("continuation from the nominal model") and note.endswith("not kept")
    _, _, _, none = continuation_from_nominal(job, aug, state, res)
    assert none == ""  # no second origin: nothing to do


def test_the_rescue_without_continuation_runs_only_the_staged_schedule(doc, compliance):
    """``continuation=False``: the rescue's note names no band continuation; with it, it
    does (a refit far above the noise level: the candidate's mode out of the band, fixed)."""
    from bondid.diagnose.rescue import rescue
    from bondid.diagnose.runner import _fit

    c, exact, data = compliance
    job = replace(_job(doc, c, data, exact * np.array([40.0, 1e-3])), alt_urdf=None)
    aug, state, res = _fit(job)
    _, _, with_cont = rescue(aug.refit, state, res, 10, 20)
    _, _, without = rescue(aug.refit, state, res, 10, 20, continuation=False)
    assert "band continuation" in with_cont
    assert without and "band continuation" not in without


def test_the_rescue_told_to_run_always_runs_every_fallback_below_its_ratio(
    doc, compliance, monkeypatch
):  # type: ignore[no-untyped-def]
    """With the rescue's ratios raised out of reach the refit counts as at the noise level
    and the rescue does nothing; ``always=True`` (the final fit's) still runs the band
    continuation and the staged schedule, and never returns a point of higher objective."""
    from bondid.diagnose import rescue as rescue_module
    from bondid.diagnose.runner import _fit

    c, exact, data = compliance
    job = replace(_job(doc, c, data, exact), alt_urdf=None)
    aug, state, res = _fit(job)
    monkeypatch.setattr(rescue_module, "RESCUE_RATIO", 1e9)
    monkeypatch.setattr(rescue_module, "STAGED_RATIO", 1e9)
    s1, _, quiet = rescue_module.rescue(aug.refit, state, res, 10, 20)
    assert quiet == "" and s1 is state
    s2, _, note = rescue_module.rescue(aug.refit, state, res, 10, 20, always=True)
    assert "band continuation to" in note and "staged schedule to" in note, note
    assert aug.refit.cost(s2) <= aug.refit.cost(state)


def test_a_refit_that_misses_the_heldout_data_is_stuck(doc, compliance, monkeypatch):
    """Known answer for the held-out test of ``stuck`` (the training test is held False
    here): with the held-out noise level set to the refit's own held-out figure on data of
    the same machine, the refit is not stuck there; on held-out data of another machine (the
    nominal model without the compliance) it is; without a level only the training test
    counts."""
    from bondid.diagnose import alternatives
    from bondid.diagnose.evaluate import heldout_rms
    from bondid.diagnose.runner import _fit

    c, exact, data = compliance
    job = _job(doc, c, data, exact)
    aug, state, res = _fit(job)
    monkeypatch.setattr(alternatives, "above_noise", lambda refit, state: False)
    own = heldout_rms(aug.refit, res.result, data, job.options)  # its figure [dB]
    same = replace(job, heldout_noise_db=own)
    assert not alternatives.stuck(same, aug, state, res)
    other = _data(doc)
    assert alternatives.stuck(replace(same, heldout=other), aug, state, res)
    assert not alternatives.stuck(replace(job, heldout=other), aug, state, res)  # no level

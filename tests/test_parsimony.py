"""The simpler of two FRF modifiers the data cannot tell apart (bondid.diagnose.parsimony):
a delay on every output and a lag on every input within the noise of each other, and the
cases where nothing may move (a lag the data do tell from the delay, other entries of the
FRF, structural candidates)."""

from __future__ import annotations

import numpy as np

from bondid.diagnose import scoring
from bondid.diagnose.decide import verdict_order
from bondid.diagnose.effects import available
from bondid.diagnose.job import JobResult
from bondid.diagnose.parsimony import entries, prefer_simpler

CHANNELS = ("rot", "ext", "lift")
#: the held-out noise reference of the measured case (module docstring of parsimony.py)
NOISE = scoring.NoiseReference(0.881, 169.7)


def _candidate(effect: str, location: str):
    from pathlib import Path

    from bondid.model import UrdfDocument

    doc = UrdfDocument.load(Path(__file__).resolve().parents[1] / "tools" / "benchmark"
                            / "designs" / "polar_handler.urdf")  # fmt: skip
    return next(c for c in available()[effect]().candidates(doc) if c.location == location)


def _result(effect: str, location: str) -> JobResult:
    """A refit of the candidate whose strength the data determine (value/std 100)."""
    cand = _candidate(effect, location)
    n = len(cand.parameters)
    values = np.array([1.0] + [p.initial for p in cand.parameters])
    std = np.r_[0.1, values[1:] / 100.0]
    return JobResult(
        cand.label, cand.effect, cand.location, [f"p{i}" for i in range(values.size)], values,
        std, n, 1.0, 1.0, 100, 1.0, 1.0, [], "", 0.0, candidate=cand, n_own=n,
    )  # fmt: skip


def _pick(results, scores):
    order = verdict_order(results, scores)
    return prefer_simpler(results, scores, order, NOISE, CHANNELS, CHANNELS)


def test_modifier_entries() -> None:
    delay, lag = _candidate("sensor_delay", "all"), _candidate("actuator_lag", "all")
    assert entries(delay, CHANNELS, CHANNELS).all() and entries(lag, CHANNELS, CHANNELS).all()
    row = entries(_candidate("sensor_delay", "ext"), CHANNELS, CHANNELS)
    col = entries(_candidate("actuator_lag", "ext"), CHANNELS, CHANNELS)
    assert row[1].all() and not row[[0, 2]].any()
    assert col[:, 1].all() and not col[:, [0, 2]].any()
    assert entries(_candidate("soft_mounts", "pedestal"), CHANNELS, CHANNELS) is None


def test_a_delay_within_the_noise_of_a_lag_on_every_channel_is_tested_first() -> None:
    lag, delay = _result("actuator_lag", "all"), _result("sensor_delay", "all")
    other = _result("sensor_delay", "rot")
    order, displaced = _pick([lag, other, delay], [0.865, 1.9, 0.867])
    assert order[0] == 2 and displaced == 0 and sorted(order) == [0, 1, 2]
    # the same scores without a noise reference: within the margins, the same choice
    order, displaced = prefer_simpler([lag, delay], [0.865, 0.867], [0, 1], None, CHANNELS,
                                      CHANNELS)  # fmt: skip
    assert order == [1, 0] and displaced == 0


def test_nothing_moves_where_the_data_tell_them_apart_or_the_entries_differ() -> None:
    lag, delay = _result("actuator_lag", "all"), _result("sensor_delay", "all")
    # the lag's refit beats the delay's beyond the noise (blind benchmark, gantry, a withheld
    # lag on every input: 0.575 against 1.03 dB)
    assert _pick([lag, delay], [0.575, 1.03]) == ([0, 1], None)
    # a lag on one input and a delay on its output: other entries of the FRF
    lag_ext, delay_ext = _result("actuator_lag", "ext"), _result("sensor_delay", "ext")
    assert _pick([lag_ext, delay_ext], [0.865, 0.867]) == ([0, 1], None)
    # the simpler one already first, and a structural best: nothing to do
    assert _pick([delay, lag], [0.865, 0.867]) == ([0, 1], None)
    sm = _result("soft_mounts", "pedestal")
    assert _pick([sm, delay], [0.865, 0.867]) == ([0, 1], None)


def test_an_undetermined_simpler_refit_is_not_preferred() -> None:
    lag, delay = _result("actuator_lag", "all"), _result("sensor_delay", "all")
    delay.std[-1] = delay.values[-1]  # value/std 1 < Z
    assert _pick([lag, delay], [0.865, 0.867]) == ([0, 1], None)


def test_the_summary_says_which_modifier_a_simpler_one_was_named_for() -> None:
    from bondid.diagnose.summary import preferred_lines

    pref = {"effect": "actuator_lag", "location": "all", "score": 0.865, "n_parameters": 2}
    effects = [
        {"step": 1, "effect": "joint_compliance", "location": "arm->fork:ry", "test": {}},
        {"step": 2, "effect": "sensor_delay", "location": "all",
         "test": {"preferred_over": pref}},
    ]  # fmt: skip
    (line,) = preferred_lines(effects)
    assert "step 2: sensor_delay@all named for actuator_lag@all (0.865 dB)" in line
    assert preferred_lines(effects[:1]) == []

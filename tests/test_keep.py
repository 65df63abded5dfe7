"""The keep rule of two refits of one job (bondid.diagnose.keep.replaces)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from bondid.diagnose.keep import known, replaces
from bondid.diagnose.rescue import RESCUE_RATIO


def _job(level: float = 0.5, heldout: bool = True) -> SimpleNamespace:
    return SimpleNamespace(heldout=[object()] if heldout else [], heldout_noise_db=level)


def _never() -> float:
    raise AssertionError("the held-out figure was computed although not needed")


def test_a_higher_training_objective_never_replaces() -> None:
    assert not replaces(_job(), 1.0, _never, 1.0, _never)  # type: ignore[arg-type]
    assert not replaces(_job(), 1.0, _never, 1.2, _never)  # type: ignore[arg-type]


def test_without_held_out_data_the_training_objective_decides() -> None:
    assert replaces(_job(heldout=False), 1.0, _never, 0.9, _never)  # type: ignore[arg-type]


def test_a_lower_training_objective_with_a_worse_held_out_figure_is_refused() -> None:
    # the figures of benchmark case gantry/sm+al/acc in stop 22 (training 0.751 -> 0.739 dB,
    # held-out 0.87 -> 1.87 dB; the truth model's figures were about 0.5 dB)
    assert not replaces(_job(0.5), 0.751**2, known(0.87), 0.739**2, known(1.87))  # type: ignore[arg-type]


def test_a_lower_training_objective_with_a_better_held_out_figure_replaces() -> None:
    assert replaces(_job(0.5), 1.0, known(2.0), 0.5, known(1.9))  # type: ignore[arg-type]


def test_a_held_out_figure_at_the_noise_level_is_enough() -> None:
    level = 0.5
    at_level = 0.99 * RESCUE_RATIO * level
    # worse than the current refit's, but at the held-out noise level: the current one's
    # figure is not even needed
    assert replaces(_job(level), 1.0, _never, 0.9, known(at_level))  # type: ignore[arg-type]
    above = 1.01 * RESCUE_RATIO * level
    assert not replaces(_job(level), 1.0, known(0.55), 0.9, known(above))  # type: ignore[arg-type]


@pytest.mark.parametrize("level", [math.nan, 0.0])
def test_without_a_noise_level_the_held_out_figures_are_compared(level: float) -> None:
    assert replaces(_job(level), 1.0, known(0.60), 0.9, known(0.59))  # type: ignore[arg-type]
    assert not replaces(_job(level), 1.0, known(0.60), 0.9, known(0.61))  # type: ignore[arg-type]


def test_an_unknown_held_out_figure_leaves_the_training_objective_to_decide() -> None:
    assert replaces(_job(0.5), 1.0, known(0.6), 0.9, known(math.nan))  # type: ignore[arg-type]
    assert replaces(_job(0.5), 1.0, known(math.nan), 0.9, known(2.0))  # type: ignore[arg-type]


def test_the_note_says_why_a_lower_retry_was_refused() -> None:
    from bondid.diagnose.alternatives import HELD_OUT_WORSE, kept_note

    assert kept_note("restart", 0.94, False, lower=True).endswith(f"not kept ({HELD_OUT_WORSE})")
    assert kept_note("restart", 1.5, False).endswith("not kept")
    assert kept_note("restart", 0.94, True, lower=True).endswith("kept")

"""The alternatives to a refit above the noise level (bondid.diagnose.alternatives) say which
alternatives failed instead of skipping them silently (the failures are injected: the model
set-up or the refit raises a numerical error)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from bondid.cost.problem import CostOptions
from bondid.diagnose import alternatives
from bondid.diagnose.effects import get_effect
from bondid.diagnose.runner import Job
from bondid.exceptions import ModelError
from bondid.model import UrdfDocument

MODEL = Path(__file__).resolve().parents[1] / "urdf" / "bonder.urdf"


@pytest.fixture(scope="module")
def doc() -> UrdfDocument:
    return UrdfDocument.load(MODEL)


def _raise(*_: Any, **__: Any) -> Any:
    raise ModelError("injected: the augmented model cannot be built")


def test_failed_pivots_are_said_in_the_pivot_note(doc, monkeypatch) -> None:
    c = next(
        c for c in get_effect("joint_compliance").candidates(doc)
        if c.location == "base->x_stage:rx"
    )  # fmt: skip
    text = doc.to_string()
    job = Job(text, None, [], [], [], replace(c, variants=()), CostOptions(), alt_urdf=text)  # type: ignore[arg-type]
    monkeypatch.setattr(alternatives, "_setup", _raise)
    moved, note, _ = alternatives.refine_job_pivot(job)
    n = int(note.split(" pivots tried", 1)[0])
    assert f"{n} of {n} pivots failed" in note
    assert "ModelError: injected" in note
    assert moved.candidate is not None and moved.candidate.spec["pivot"] == c.spec["pivot"]


class _Refit:
    """The refit's objective only (what other_variants compares)."""

    def cost(self, state: Any) -> float:
        return 1.0


class _Aug:
    refit = _Refit()


def test_failed_variants_are_said_in_the_notes(doc, monkeypatch) -> None:
    (c,) = get_effect("soft_mounts").candidates(doc)
    assert c.variants
    text = doc.to_string()
    job = Job(text, None, [], [], [], replace(c, variants=()), CostOptions(), alt_urdf=text)  # type: ignore[arg-type]
    monkeypatch.setattr(alternatives, "_fit", _raise)
    notes: dict[str, Any] = {}
    aug = _Aug()
    got = alternatives.other_variants(job, aug, None, None, notes)  # type: ignore[arg-type]
    assert got[0] is job and got[1] is aug  # nothing replaced it
    n = len(c.variants)  # every variant but the one refitted already
    assert f"{n} of {n} other variants' refits failed" in notes["variants"]
    assert "ModelError: injected" in notes["variants"]

"""The report's first screen and its filing: the verdict with and without ``verdict.outcome``,
the remainder, channels left out per file, plots under the command whose manifest lists them."""

from __future__ import annotations

import json
import re
from pathlib import Path

from test_report import _png

from bondid.report.build import build_report_html
from bondid.report.headline import diagnosis_headline, fit_headline

FIT = {
    "status": "Solve_Succeeded", "success": True, "iterations": 12, "wall_s": 1.0,
    "parameters": [{"name": "k", "unit": "N/m", "initial": 1.0, "fitted": 2.0, "lower": 0.5,
                    "upper": 2.0, "std": None}],
    "db_rms": {"initial": 9.0, "final": 1.5, "noise_level": 0.5, "weighting": "auto",
               "no_figure": ["x.y in b.csv (final model): the model's FRF is zero"],
               "by_dataset": [
                   {"file": "data/a.csv", "by_channel": {"x.x": {"initial": 9.0, "final": 1.4}}},
                   {"file": "data/b.csv", "by_channel": {"x.x": {"initial": 9.1, "final": 1.6}}}]},
    "channels_by_file": [{"file": "data/a.csv", "used": ["x.x"], "left_out": {"y.x": 0.1}},
                         {"file": "data/b.csv", "used": ["x.x"],
                          "left_out": {"y.x": 0.2, "x.y": 0.3}}],
}  # fmt: skip


def test_fit_headline_figures():
    h = fit_headline(FIT)
    assert h is not None and h.before == 9.0 and h.after == 1.5
    assert h.ratio == 3.0 and h.at_noise is False and "3.0× the noise level" in h.meaning
    assert h.on_bound == ["k"]  # fitted = upper
    assert h.left_out == ["y.x", "x.y in b.csv"]  # y.x everywhere, x.y in one file
    assert h.no_figure == FIT["db_rms"]["no_figure"]


def test_verdict_without_the_outcome_field():
    base = {"verdict": {"effect": "none", "location": None, "gap_closed": 0.0},
            "gap": {"db_rms": 0.5, "by_channel": {"x.x": 0.4, "x.y": 1.1}}}  # fmt: skip
    at_noise = dict(base, scoring={"steps": [{"base_above_noise": False, "base_over_noise": 1.02}]})
    d = diagnosis_headline(at_noise)
    assert d is not None and d.title == "Explained by the model's parameters" and d.tone == "ok"
    assert d.over_noise == 1.02 and d.worst_channels[0] == ("x.y", 1.1)
    above = dict(base, scoring={"steps": [{"base_above_noise": True}]})
    d = diagnosis_headline(above)
    assert d is not None and d.title == "Not explained" and d.tone == "bad"
    found = {"verdict": {"effect": "joint_compliance", "location": "a->b:rz", "gap_closed": 0.6,
                         "where": {"db_rms": 0.8, "by_channel": {"x.x": 0.7}}},
             "gap": {"db_rms": 2.0}}  # fmt: skip
    d = diagnosis_headline(found)
    assert d is not None and d.title == "Explained" and d.gap_after == 0.8
    assert d.effect == "joint_compliance" and d.location == "a->b:rz"


def test_verdict_outcome_and_remainder_rendered(tmp_path: Path):
    res = tmp_path / "r"
    (res / "diag").mkdir(parents=True)
    (res / "fit.json").write_text(json.dumps(FIT))
    diag = {
        "verdict": {"effect": "soft_mounts", "location": "base", "gap_closed": 0.45,
                    "outcome": "partly_explained"},
        "remainder": [{"kind": "missing_mode", "text": "480 Hz in x.y", "f_hz": 480.0},
                      {"kind": "band", "text": "above 2 kHz"}],
        "gap": {"db_rms": 2.0},
    }  # fmt: skip
    (res / "diag" / "diagnosis.json").write_text(json.dumps(diag))
    # the diagnosis's Bode plot, listed by its run manifest: filed under Diagnosis
    (res / "diag" / "bode_1.png").write_bytes(_png((5, 5, 5)))
    (res / "diag" / "diagnose.manifest.json").write_text(
        json.dumps({"command": "bondid.diagnose", "files": [{"name": "bode_1.png"}]})
    )
    (res / "bode_a.png").write_bytes(_png((6, 6, 6)))  # next to fit.json: the fit's
    page, found = build_report_html(res, res)
    assert [p.name for p in found.figures["diagnosis"]] == ["bode_1.png"]
    assert [p.name for p in found.figures["fit"]] == ["bode_a.png"]
    card = page[page.index('id="diagnosis-headline"') : page.index('id="fit"')]
    assert "Partly explained: soft_mounts at base" in card and "45.0 %" in card
    assert "missing mode: 480 Hz in x.y" in card and "band: above 2 kHz" in card
    head = page[page.index('id="fit-headline"') : page.index('id="diagnosis-headline"')]
    assert "3.0× the noise level" in head and "1 of 1 parameters on a bound" in head
    assert "No finite figure: x.y in b.csv" in head and "nan" not in head.lower()
    # channels left out: greyed rows, labelled, per file
    muted = re.findall(r'<tr class="muted">(.*?)</tr>', page)
    assert len(muted) == 3 and all("left out" in m for m in muted)
    assert any("x.y" in m and "b.csv" in m for m in muted)
    # units column and the std footnote
    assert '<td class="l">N/m</td>' in page and "not determined by these data" in page


def test_several_kept_effects_lead_the_card_together(tmp_path: Path):
    # two effects kept: the card names both and the gap after both, not the first's share
    diag = {
        "verdict": {"effect": "actuator_lag", "location": "rot", "gap_closed": 0.1,
                    "outcome": "explained"},
        "effects": [
            {"effect": "actuator_lag", "location": "rot", "db_rms_after": 3.1},
            {"effect": "joint_compliance", "location": "arm->fork:ty", "db_rms_after": 0.8},
        ],
        "gap": {"db_rms": 3.2},
    }  # fmt: skip
    d = diagnosis_headline(diag)
    assert d is not None and d.effects == [("actuator_lag", "rot"),
                                           ("joint_compliance", "arm->fork:ty")]  # fmt: skip
    assert d.gap_after == 0.8 and d.gap_closed == 1.0 - 0.8 / 3.2
    res = tmp_path / "r"
    res.mkdir()
    (res / "diagnosis.json").write_text(json.dumps(diag))
    page, _ = build_report_html(res, res)
    card = page[page.index('id="diagnosis-headline"') :]
    card = card[: card.index("</div>")]
    assert "Explained: actuator_lag at rot + joint_compliance at arm-&gt;fork:ty" in card
    assert "Together the effects close <b>75.0 %</b>" in card and "3.2 dB → 0.8 dB" in card
    # one effect: as before
    one = dict(diag, effects=diag["effects"][:1])
    d = diagnosis_headline(one)
    assert d is not None and d.gap_closed == 0.1 and d.effects == [("actuator_lag", "rot")]

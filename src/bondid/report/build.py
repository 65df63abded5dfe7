"""Gather a results folder into one self-contained, offline HTML page: :func:`build_report`.

Looks (in the folder and its sub-folders) for ``fit.json``, ``sensitivity.json``,
``diagnosis.json``, ``modes.json`` and PNG plots; each part that is present becomes a
section, each missing one a short note. PNGs are embedded as base64 data URIs; the page has
no scripts and no external references; links to mode animations are relative.
"""

from __future__ import annotations

import datetime as dt
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..atomic import write_text_atomic
from ..exceptions import ConfigError
from . import sections
from .html import esc, note, page, png_figure

RESULT_FILES = ("fit.json", "sensitivity.json", "diagnosis.json", "modes.json", "fleet.json")
#: in a fleet's results folder (fleet.json at the top), the per-machine results are not
#: gathered into the fleet's page (report on OUT/machines/<id> for one machine)
FLEET_MACHINES = "machines"
REPORT_NAME = "report.html"

# (section, words in a PNG's file name that put it there), first match wins
_FIGURE_GROUPS = (
    ("fleet", ("fleet",)),
    ("fit", ("bode", "conver", "cost")),
    ("sensitivity", ("sensitiv", "heat", "sweep")),
    ("diagnosis", ("residual", "diagnos", "gap", "candidate")),
)


_SINGLE = {
    "fit": "fit.json",
    "sensitivity": "sensitivity.json",
    "diagnosis": "diagnosis.json",
    "modes": "modes.json",
}


@dataclass
class Found:
    """What a results folder holds: JSON files by name, PNGs by section."""

    json_paths: dict[str, Path] = field(default_factory=dict)
    figures: dict[str, list[Path]] = field(default_factory=dict)

    @property
    def empty(self) -> bool:
        return not self.json_paths and not any(self.figures.values())


def scan(results: Path) -> Found:
    """Find the result files under ``results`` (shallowest first; hidden folders skipped)."""
    found = Found()
    fleet = (results / "fleet.json").is_file()
    files = sorted(
        (
            p
            for p in results.rglob("*")
            if p.is_file()
            and not any(part.startswith(".") for part in p.relative_to(results).parts)
            and not (fleet and p.relative_to(results).parts[0] == FLEET_MACHINES)
        ),
        key=lambda p: (len(p.relative_to(results).parts), p.as_posix()),
    )
    for p in files:
        if p.name in RESULT_FILES and p.name not in found.json_paths:
            found.json_paths[p.name] = p
        elif p.suffix.lower() == ".png":
            name = p.name.lower()
            group = next(
                (g for g, words in _FIGURE_GROUPS if any(w in name for w in words)), "other"
            )
            found.figures.setdefault(group, []).append(p)
    return found


def _load(path: Path) -> tuple[Any, str | None]:
    try:
        return json.loads(path.read_text(encoding="utf-8")), None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        return None, f"could not read {path.name}: {exc}"


def build_report_html(results: Path, out_dir: Path) -> tuple[str, Found]:
    """The report page for ``results`` (links relative to ``out_dir``) and what was found.

    Raises:
        ConfigError: ``results`` is not a folder, or holds no result file or PNG.
    """
    check_results_dir(results)
    found = scan(results)
    if found.empty:
        raise ConfigError(
            f"{results}: no result files ({', '.join(RESULT_FILES)}) or PNG plots found"
        )
    parts: list[str] = []
    nav: list[str] = []

    fleet_page = "fleet.json" in found.json_paths

    def section(key: str, title: str, body: str) -> None:
        if fleet_page and key in _SINGLE and _SINGLE[key] not in found.json_paths:
            return  # a fleet's page: no "not found" notes for single-machine results
        nav.append(f'<a href="#{key}">{esc(title)}</a>')
        parts.append(f'<section id="{key}"><h2>{esc(title)}</h2>{body}</section>')

    def figures(group: str, rel: Path) -> str:
        return "".join(
            png_figure(p, p.relative_to(rel).as_posix()) for p in found.figures.get(group, [])
        )

    def json_part(name: str, render, hint: str) -> str:
        path = found.json_paths.get(name)
        if path is None:
            return note(f"{name} not found — {hint}")
        data, err = _load(path)
        if err is not None:
            print(f"warning: {err}", file=sys.stderr)
            return f'<p class="warn">{esc(err)}</p>'
        return f'<p class="note">from {esc(path.relative_to(results).as_posix())}</p>' + render(
            data
        )

    if "fleet.json" in found.json_paths:
        section(
            "fleet",
            "Fleet",
            json_part("fleet.json", sections.fleet_section, "run python -m bondid.fleet")
            + figures("fleet", results),
        )
    section(
        "fit",
        "Fit",
        json_part("fit.json", sections.fit_section, "run python -m bondid.fit")
        + figures("fit", results),
    )
    section(
        "sensitivity",
        "Sensitivity",
        json_part(
            "sensitivity.json", sections.sensitivity_section, "run python -m bondid.sensitivity"
        )
        + figures("sensitivity", results),
    )
    section(
        "diagnosis",
        "Diagnosis",
        json_part("diagnosis.json", sections.diagnosis_section, "run python -m bondid.diagnose")
        + figures("diagnosis", results),
    )
    modes_path = found.json_paths.get("modes.json")
    modes_dir = modes_path.parent if modes_path is not None else results
    section(
        "modes",
        "Modes",
        json_part(
            "modes.json",
            lambda d: sections.modes_section(d, modes_dir, out_dir),
            "run python -m bondid.modes --out DIR",
        ),
    )
    if found.figures.get("other"):
        section("plots", "Other plots", figures("other", results))

    now = dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    listed = ", ".join(esc(p.relative_to(results).as_posix()) for p in found.json_paths.values())
    head = (
        f"<h1>bondid report — {esc(results.resolve().name)}</h1>"
        f"<p>Results folder <code>{esc(results)}</code>, report made {esc(now)}."
        f" Result files: {listed or 'none (plots only)'}.</p>"
        f"<nav>{''.join(nav)}</nav>"
    )
    return page(f"bondid report — {results.resolve().name}", head + "".join(parts)), found


def build_report(results: str | Path, out_dir: str | Path | None = None) -> Path:
    """Write ``report.html`` for the results folder into ``out_dir`` (default: the folder).

    Returns:
        The path of the written page.
    """
    res = Path(results)
    check_results_dir(res)
    out = res if out_dir is None else Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out}: exists and is not a folder")
    text, _ = build_report_html(res, out)
    return write_text_atomic(out / REPORT_NAME, text)


def check_results_dir(results: Path) -> None:
    """Raise :class:`ConfigError` naming RESULTS_DIR when it is not a folder."""
    if not results.is_dir():
        what = "is a file" if results.exists() else "does not exist"
        raise ConfigError(
            f"{results}: the results folder {what}; valid: a folder written by bondid.fit,"
            " bondid.sensitivity, bondid.diagnose or bondid.modes"
        )


def manifest_warnings(results: Path) -> list[str]:
    """Problems with the run manifests under ``results`` (:mod:`bondid.results`): a listed
    file missing or changed since its run wrote it."""
    from ..exceptions import DataError
    from ..results import read_manifest

    out = []
    for m in sorted(results.rglob("*.manifest.json")):
        command = m.name[: -len(".manifest.json")]
        try:
            read_manifest(m.parent, command)
        except DataError as exc:
            out.append(str(exc))
    return out

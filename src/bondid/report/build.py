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
from collections.abc import Callable
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


# (section key and title, its result file, its renderer, what to run when it is missing);
# the key also names the section's figure group
_SECTIONS: tuple[tuple[str, str, str, Callable[[Any], str], str], ...] = (
    ("fit", "Fit", "fit.json", sections.fit_section, "run python -m bondid.fit"),
    (
        "sensitivity", "Sensitivity", "sensitivity.json", sections.sensitivity_section,
        "run python -m bondid.sensitivity",
    ),
    (
        "diagnosis", "Diagnosis", "diagnosis.json", sections.diagnosis_section,
        "run python -m bondid.diagnose",
    ),
)  # fmt: skip


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
    pg = _Page(results, found)
    if "fleet.json" in found.json_paths:
        hint = "run python -m bondid.fleet"
        body = pg.json_part("fleet.json", sections.fleet_section, hint) + pg.figures("fleet")
        pg.section("fleet", "Fleet", body)
    for key, title, name, render, hint in _SECTIONS:
        pg.section(key, title, pg.json_part(name, render, hint) + pg.figures(key))
    modes_path = found.json_paths.get("modes.json")
    modes_dir = modes_path.parent if modes_path is not None else results
    pg.section(
        "modes",
        "Modes",
        pg.json_part(
            "modes.json",
            lambda d: sections.modes_section(d, modes_dir, out_dir),
            "run python -m bondid.modes --out DIR",
        ),
    )
    if found.figures.get("other"):
        pg.section("plots", "Other plots", pg.figures("other"))
    return page(f"bondid report — {results.resolve().name}", pg.html()), found


@dataclass
class _Page:
    """The report page being assembled: its sections and the navigation bar linking them."""

    results: Path
    found: Found
    parts: list[str] = field(default_factory=list)
    nav: list[str] = field(default_factory=list)

    def section(self, key: str, title: str, body: str) -> None:
        """Add a section (on a fleet's page, only those whose result file is there)."""
        fleet_page = "fleet.json" in self.found.json_paths
        if fleet_page and key in _SINGLE and _SINGLE[key] not in self.found.json_paths:
            return  # a fleet's page: no "not found" notes for single-machine results
        self.nav.append(f'<a href="#{key}">{esc(title)}</a>')
        self.parts.append(f'<section id="{key}"><h2>{esc(title)}</h2>{body}</section>')

    def figures(self, group: str) -> str:
        """The PNGs of figure group ``group``, embedded."""
        return "".join(
            png_figure(p, p.relative_to(self.results).as_posix())
            for p in self.found.figures.get(group, [])
        )

    def json_part(self, name: str, render: Callable[[Any], str], hint: str) -> str:
        """Result file ``name`` rendered, or a note that it is missing or unreadable."""
        path = self.found.json_paths.get(name)
        if path is None:
            return note(f"{name} not found — {hint}")
        data, err = _load(path)
        if err is not None:
            print(f"warning: {err}", file=sys.stderr)
            return f'<p class="warn">{esc(err)}</p>'
        source = esc(path.relative_to(self.results).as_posix())
        return f'<p class="note">from {source}</p>' + render(data)

    def html(self) -> str:
        """The page body: heading, navigation bar, then the sections."""
        now = dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
        results = self.results
        listed = ", ".join(
            esc(p.relative_to(results).as_posix()) for p in self.found.json_paths.values()
        )
        head = (
            f"<h1>bondid report — {esc(results.resolve().name)}</h1>"
            f"<p>Results folder <code>{esc(results)}</code>, report made {esc(now)}."
            f" Result files: {listed or 'none (plots only)'}.</p>"
            f"<nav>{''.join(self.nav)}</nav>"
        )
        return head + "".join(self.parts)


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

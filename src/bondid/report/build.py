"""Gather a results folder into one self-contained, offline HTML page: :func:`build_report`.

Looks (in the folder and its sub-folders) for ``fit.json``, ``sensitivity.json``,
``diagnosis.json``, ``modes.json`` and PNG plots. The page opens with the answer (the fit's
headline and the diagnosis's verdict, :mod:`.headline`), then one section per command with
its tables and its own plots. A PNG belongs to the command whose run manifest lists it
(:mod:`bondid.results`), else to the one result file in its folder, else to the words of its
name. PNGs are embedded as base64 data URIs; the page (jinja2 templates under
``templates/``) has no scripts and no external references; links to mode animations are
relative.
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
from .blocks import Block, Section, note, warn
from .diagnosis_section import diagnosis_section
from .fit_section import fit_section
from .fleet_section import fleet_section
from .headline import diagnosis_headline, fit_headline
from .html import png_figure, render
from .modes_section import modes_section
from .sensitivity_section import sensitivity_section

RESULT_FILES = ("fit.json", "sensitivity.json", "diagnosis.json", "modes.json", "fleet.json")
#: in a fleet's results folder (fleet.json at the top), the per-machine results are not
#: gathered into the fleet's page (report on OUT/machines/<id> for one machine)
FLEET_MACHINES = "machines"
REPORT_NAME = "report.html"

#: the section of each command's results (from its run manifest's ``command``)
_COMMAND_SECTION = {
    "bondid.fit": "fit",
    "bondid.sensitivity": "sensitivity",
    "bondid.diagnose": "diagnosis",
    "bondid.fleet": "fleet",
    "bondid.modes": "modes",
    "bondid.simulate": "other",
}
_FILE_SECTION = {
    "fit.json": "fit",
    "sensitivity.json": "sensitivity",
    "diagnosis.json": "diagnosis",
    "modes.json": "modes",
    "fleet.json": "fleet",
}
# (section, words in a PNG's file name that put it there), first match wins: the last resort
_FIGURE_GROUPS = (
    ("fleet", ("fleet",)),
    ("diagnosis", ("residual", "diagnos", "gap", "candidate")),
    ("fit", ("bode", "conver", "cost")),
    ("sensitivity", ("sensitiv", "heat", "sweep")),
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


def _manifest_owners(folder: Path) -> dict[str, str]:
    """``{file name: section}`` from the run manifests in ``folder``."""
    owners: dict[str, str] = {}
    for m in folder.glob("*.manifest.json"):
        try:
            doc = json.loads(m.read_text(encoding="utf-8"))
            section = _COMMAND_SECTION.get(str(doc.get("command")))
            names = [str(f["name"]) for f in doc.get("files", [])]
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            continue
        if section is not None:
            owners.update(dict.fromkeys(names, section))
    return owners


def _figure_section(p: Path, owners: dict[Path, dict[str, str]], files: list[Path]) -> str:
    """The section a PNG belongs to (module docstring)."""
    folder = p.parent
    if folder not in owners:
        owners[folder] = _manifest_owners(folder)
    if p.name in owners[folder]:
        return owners[folder][p.name]
    here = {_FILE_SECTION[f.name] for f in files if f.parent == folder and f.name in _FILE_SECTION}
    if len(here) == 1:
        return here.pop()
    name = p.name.lower()
    return next((g for g, words in _FIGURE_GROUPS if any(w in name for w in words)), "other")


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
    owners: dict[Path, dict[str, str]] = {}
    for p in files:
        if p.name in RESULT_FILES and p.name not in found.json_paths:
            found.json_paths[p.name] = p
        elif p.suffix.lower() == ".png":
            found.figures.setdefault(_figure_section(p, owners, files), []).append(p)
    return found


def _load(path: Path) -> tuple[Any, str | None]:
    try:
        return json.loads(path.read_text(encoding="utf-8")), None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        return None, f"could not read {path.name}: {exc}"


# (section key and title, its result file, its renderer, what to run when it is missing)
_SECTIONS: tuple[tuple[str, str, str, Callable[[Any], list[Block]], str], ...] = (
    ("fit", "Fit", "fit.json", fit_section, "run python -m bondid.fit"),
    (
        "diagnosis",
        "Diagnosis",
        "diagnosis.json",
        diagnosis_section,
        "run python -m bondid.diagnose",
    ),
    (
        "sensitivity",
        "Sensitivity",
        "sensitivity.json",
        sensitivity_section,
        "run python -m bondid.sensitivity",
    ),
)


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
        pg.add("fleet", "Fleet", "fleet.json", fleet_section, "run python -m bondid.fleet")
    for key, title, name, render_fn, hint in _SECTIONS:
        pg.add(key, title, name, render_fn, hint)
    modes_path = found.json_paths.get("modes.json")
    modes_dir = modes_path.parent if modes_path is not None else results
    pg.add(
        "modes",
        "Modes",
        "modes.json",
        lambda d: modes_section(d, modes_dir, out_dir),
        "run python -m bondid.modes --out DIR",
    )
    if found.figures.get("other"):
        pg.sections.append(Section("plots", "Other plots", pg.figures("other")))
    now = dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    text = render(
        "report.html.j2",
        title=f"bondid report — {results.resolve().name}",
        folder=str(results),
        made=now,
        files=[p.relative_to(results).as_posix() for p in found.json_paths.values()],
        fit=fit_headline(pg.data.get("fit.json")),
        diagnosis=diagnosis_headline(pg.data.get("diagnosis.json")),
        sections=pg.sections,
    )
    return text, found


@dataclass
class _Page:
    """The report page being assembled: its sections and the result files read."""

    results: Path
    found: Found
    sections: list[Section] = field(default_factory=list)
    data: dict[str, Any] = field(default_factory=dict)

    def add(
        self, key: str, title: str, name: str, render_fn: Callable[[Any], list[Block]], hint: str
    ) -> None:
        """Add the section of result file ``name`` and of the figures of group ``key`` (on a
        fleet's page, only those whose result file is there)."""
        fleet_page = "fleet.json" in self.found.json_paths
        if fleet_page and key in _SINGLE and _SINGLE[key] not in self.found.json_paths:
            return  # a fleet's page: no "not found" notes for single-machine results
        path = self.found.json_paths.get(name)
        source = None
        if path is None:
            blocks = [note(f"{name} not found — {hint}")]
        else:
            data, err = _load(path)
            if err is not None:
                print(f"warning: {err}", file=sys.stderr)
                blocks = [warn(err)]
            else:
                self.data[name] = data
                source = path.relative_to(self.results).as_posix()
                blocks = render_fn(data)
        self.sections.append(Section(key, title, blocks + self.figures(key), source))

    def figures(self, group: str) -> list[Block]:
        """The PNGs of figure group ``group``, embedded (one block, or none)."""
        figs = [
            png_figure(p, p.relative_to(self.results).as_posix())
            for p in self.found.figures.get(group, [])
        ]
        return [Block("figures", figures=figs)] if figs else []


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

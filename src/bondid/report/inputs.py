"""What ``bondid.report`` checks in a results folder before it renders anything.

* :func:`check_folder` — the folder is a folder; no commit into it was interrupted (unless
  the report writes into it and so restores the previous run first, :mod:`bondid.journal`);
  every file the report would read (result files, manifests, PNGs) is a regular file inside
  the folder (a FIFO would block the report, a link may point anywhere).
* :func:`check_result_json` — each result file that parses as JSON has the shape its command
  writes (:data:`SCHEMAS`): ``fit.json`` = ``[1, 2, 3]`` or a ``modes`` that is a number is
  refused (:class:`~bondid.exceptions.DataError`, exit 2) naming the file and the key. A file
  that is not JSON at all is left to the page, which says it could not be read.
* :func:`manifest_warnings` — each command's manifest: malformed or naming a file its
  command never writes → refused (exit 2); a listed file missing or changed, a result file
  without its manifest (an interrupted run, or files put together by hand), a result file
  of the command that its manifest does not list (from another run) → a warning, printed and
  shown on the page.
"""

from __future__ import annotations

import fnmatch
import json
import os
import stat
from pathlib import Path
from typing import Any

from ..exceptions import ConfigError, DataError, ManifestError
from ..journal import pending
from ..manifest import RESULT_PATTERNS, manifest_name, read_manifest

#: result file → (command that writes it, its schema); a schema is a type name ("object",
#: "list", "str", "num", "int", "bool"; "?" suffix: null allowed) or a dict:
#: {"type": ..., "keys": {key: schema}, "required": (...), "items": schema, "values": schema}
_NUM = "num?"
_PARAM = {"type": "object", "required": ("name",),
          "keys": {"name": "str", **{k: _NUM for k in
                   ("initial", "fitted", "lower", "upper", "std")}}}  # fmt: skip
_OBJECTS = {"type": "list", "items": "object"}
SCHEMAS: dict[str, tuple[str, dict[str, Any]]] = {
    "fit.json": ("fit", {
        "type": "object", "required": ("status", "parameters"),
        "keys": {"status": "str", "cost_initial": _NUM, "cost_final": _NUM,
                 "cost_name": "str?", "iterations": "int?", "wall_s": _NUM,
                 "warnings": {"type": "list", "items": "str"},
                 "parameters": {"type": "list", "items": _PARAM}},
    }),
    "diagnosis.json": ("diagnose", {
        "type": "object", "required": ("gap", "candidates", "verdict"),
        "keys": {
            "gap": {"type": "object?", "keys": {
                "db_rms": _NUM, "by_channel": {"type": "object", "values": _NUM},
                "by_band": {"type": "list", "items": {"type": "object", "keys": {
                    "f_lo_hz": _NUM, "f_hi_hz": _NUM, "db_rms": _NUM}}},
                "modes": {"type": "list", "items": {"type": "object", "keys": {
                    "f_measured_hz": _NUM, "f_model_hz": _NUM, "status": "str?"}}}}},
            "candidates": {"type": "list", "items": {"type": "object", "keys": {
                "effect": "str?", "db_rms_after": _NUM, "gap_closed": _NUM,
                "heldout_db_rms_after": _NUM, "score": _NUM}}},
            "verdict": {"type": "object?", "keys": {"effect": "str?", "gap_closed": _NUM}},
            "effects": _OBJECTS, "dropped": _OBJECTS,
        },
    }),
    "modes.json": ("modes", {
        "type": "object", "required": ("modes",),
        "keys": {"modes": {"type": "list", "items": {"type": "object", "keys": {
                     "f_hz": _NUM, "zeta": _NUM, "index": "int?", "kind": "str?",
                     "html": "str?", "dominant_dof": "str?"}}},
                 "operating_point": {"type": "object?", "values": _NUM},
                 "fitted": {"type": "object?", "keys": {"modes": _OBJECTS}}},
    }),
    "sensitivity.json": ("sensitivity", {
        "type": "object", "required": ("parameters",),
        "keys": {"parameters": "list", "channels": "list?", "warnings": "list?"},
    }),
    "fleet.json": ("fleet", {
        "type": "object", "required": ("machines",),
        "keys": {"counts": {"type": "object?", "values": "int?"}, "machines": _OBJECTS,
                 "parameters": _OBJECTS, "outliers": _OBJECTS, "rows": _OBJECTS},
    }),
}  # fmt: skip

_WORDS = {
    "object": "a JSON object", "list": "a list", "str": "a text", "num": "a number",
    "int": "an integer", "bool": "true or false",
}  # fmt: skip


def _is(value: Any, kind: str) -> bool:
    if kind.endswith("?"):
        return value is None or _is(value, kind[:-1])
    if kind == "object":
        return isinstance(value, dict)
    if kind == "list":
        return isinstance(value, list)
    if kind == "str":
        return isinstance(value, str)
    if kind == "bool":
        return isinstance(value, bool)
    if kind == "int":
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, int | float) and not isinstance(value, bool)  # num


def _what(value: Any) -> str:
    if value is None:
        return "null"
    for kind in ("bool", "object", "list", "str", "int", "num"):
        if _is(value, kind):
            return _WORDS[kind]
    return type(value).__name__


def _label(path: str) -> str:
    return "the file" if not path else f"key {path!r}"


def _check(value: Any, schema: Any, path: str, where: str, command: str) -> None:
    """Raise :class:`DataError` where ``value`` (at key ``path``, "" = the whole file)
    does not fit ``schema`` (see :data:`SCHEMAS`)."""
    spec = schema if isinstance(schema, dict) else {"type": schema}
    kind = spec["type"]
    if not _is(value, kind):
        nullable = " or null" if kind.endswith("?") else ""
        raise DataError(
            f"{where}: {_label(path)} is {_what(value)}; valid: {_WORDS[kind.rstrip('?')]}"
            f"{nullable} (as bondid.{command} writes it)"
        )
    if isinstance(value, dict):
        for req in spec.get("required", ()):
            if req not in value:
                raise DataError(
                    f"{where}: {_label(path)} has no key {req!r}; valid: a"
                    f" {Path(where).name} written by bondid.{command}"
                )
        for k, sub in spec.get("keys", {}).items():
            if k in value:
                _check(value[k], sub, f"{path}.{k}" if path else k, where, command)
        if "values" in spec:
            for k, v in value.items():
                _check(v, spec["values"], f"{path}.{k}" if path else k, where, command)
    if isinstance(value, list) and "items" in spec:
        for i, v in enumerate(value):
            _check(v, spec["items"], f"{path}[{i}]", where, command)


def check_result_json(name: str, path: Path) -> None:
    """Raise :class:`DataError` when the result file ``path`` (named ``name``, e.g.
    ``fit.json``) parses as JSON but not in the shape its command writes."""
    if name not in SCHEMAS:
        return
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return  # the page says it could not be read
    command, schema = SCHEMAS[name]
    _check(data, schema, "", str(path), command)


def _visible(results: Path) -> list[Path]:
    """The entries the report reads under ``results`` (hidden parts skipped, links not
    followed into folders)."""
    out = []
    for p in results.rglob("*"):
        rel = p.relative_to(results)
        if any(part.startswith(".") for part in rel.parts):
            continue
        out.append(p)
    return out


def check_folder(results: Path, *, restoring: bool) -> None:
    """Refuse a results folder the report cannot read safely (module docstring).

    Args:
        results: the results folder.
        restoring: the report writes into ``results`` itself (it then restores the previous
            run of an interrupted commit before reading, :mod:`bondid.results`).

    Raises:
        ConfigError: naming the folder or file and what would be valid.
    """
    if not results.is_dir():
        what = "is a file" if results.exists() else "does not exist"
        raise ConfigError(
            f"{results}: the results folder {what}; valid: a folder written by bondid.fit,"
            " bondid.sensitivity, bondid.diagnose or bondid.modes"
        )
    top = results.resolve()
    for folder in [results, *(p for p in _visible(results) if p.is_dir())]:
        stuck = pending(folder)
        if stuck and not (restoring and folder == results):
            raise ConfigError(
                f"{folder}: a run of bondid.{stuck[0]} was interrupted while replacing its"
                f" results there, so the folder mixes two runs; run python -m bondid.report"
                f" {folder} (without --out) or any bondid command with --out {folder} to"
                " restore the previous results first"
            )
    for p in _visible(results):
        name = p.name.lower()
        if not (p.name in SCHEMAS or name.endswith((".manifest.json", ".png"))):
            continue
        st = os.lstat(p)
        if stat.S_ISLNK(st.st_mode):
            target = p.resolve()
            if top not in target.parents:
                raise ConfigError(
                    f"{p}: a symbolic link to {target}, outside the results folder; valid:"
                    " result files inside the folder (bondid never writes links)"
                )
            st = os.stat(p)
        if not stat.S_ISREG(st.st_mode) and not stat.S_ISDIR(st.st_mode):
            raise ConfigError(f"{p}: not a regular file; valid: result files written by bondid")


def check_results(results: Path) -> None:
    """:func:`check_result_json` for every result file under ``results``."""
    for p in _visible(results):
        if p.name in SCHEMAS and p.is_file():
            check_result_json(p.name, p)


def manifest_warnings(results: Path) -> list[str]:
    """Problems with the run manifests under ``results`` (module docstring).

    Raises:
        ManifestError: a malformed manifest, or one naming a file its command never writes.
    """
    out: list[str] = []
    folders = [results, *(p for p in _visible(results) if p.is_dir())]
    for folder in folders:
        names = {p.name for p in folder.iterdir() if p.is_file()}
        listed: set[str] = set()
        found: dict[str, dict[str, Any] | None] = {}
        for command, patterns in RESULT_PATTERNS.items():
            if manifest_name(command) not in names or command == "report":
                continue  # (the report's own page is never read, only replaced)
            try:
                found[command] = read_manifest(folder, command, patterns=patterns)
            except ManifestError as exc:
                if "missing or differs" not in str(exc):
                    raise
                out.append(str(exc))
                found[command] = read_manifest(folder, command, verify=False, patterns=patterns)
            listed |= set((found[command] or {}).get("files_by_name", {}))
        for name, (command, _) in SCHEMAS.items():
            if name in names and command not in found:
                out.append(
                    f"{folder / name}: no {manifest_name(command)} beside it, so it is not a"
                    f" complete run of bondid.{command} (interrupted, or put together by"
                    " hand); the plots beside it may come from other runs"
                )
        for command in found:
            strays = sorted(
                n
                for n in names - listed
                if any(fnmatch.fnmatchcase(n, p) for p in RESULT_PATTERNS[command])
            )
            if strays:
                out.append(
                    f"{folder}: {', '.join(strays)} not listed in {manifest_name(command)}:"
                    f" from another run than the rest of bondid.{command}'s results"
                )
    return out


def with_warnings(page: str, warnings: list[str]) -> str:
    """The page with the folder's warnings at the top of its body (a reader of the page
    sees that the folder is incomplete or mixed, as the command line said)."""
    if not warnings:
        return page
    from html import escape

    block = "".join(f'<p class="warn">warning: {escape(w)}</p>' for w in warnings)
    head, sep, tail = page.partition("<body>")
    return head + sep + block + tail if sep else block + page

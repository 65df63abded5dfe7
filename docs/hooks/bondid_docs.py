"""MkDocs hook: the reference pages generated from the code, so they cannot drift from it.

A page writes a marker where generated text goes:

* ``<!-- bondid:cli NAME -->`` — the options of ``python -m bondid.NAME``, read from the
  argparse parser the command itself builds (the command's ``main`` is run with ``--help``
  and stopped at its first ``parse_args``: whatever parser it really uses is the one shown);
* ``<!-- bondid:schema NAME -->`` — every key of ``NAME.json`` from the JSON Schema shipped
  in the package (``bondid/schemas/NAME.schema.json``), the file the tests validate real
  outputs against;
* ``<!-- bondid:exceptions -->`` — the exception tree of :mod:`bondid.exceptions`;
* ``<!-- bondid:study-example -->`` — the annotated study file of :mod:`bondid.fit.study`'s
  docstring (every key, with the option it stands for).

An unknown name or a command whose parser cannot be read stops the build (an error, not a
warning, so ``mkdocs build --strict`` and CI catch it). The functions are plain Python, used
by the tests as well (``tests/test_docs_reference.py``).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import json
import re
from importlib import resources
from typing import Any

#: every command of the package, in the order the docs list them, with one line each
COMMANDS: dict[str, str] = {
    "fit": "fit a model's parameters to measured FRFs",
    "sensitivity": "which parameters the data determine, band by band",
    "diagnose": "where the model-to-data gap lies and which missing effect explains it",
    "modes": "modal analysis of the linearised model, mode shapes in a 3-D viewer",
    "report": "one offline HTML page from a results folder",
    "simulate": "synthetic measured FRFs of a machine model",
    "fleet": "fit (and diagnose) every machine of a fleet on Dask",
}

#: every result file with a JSON Schema, and the command that writes it
SCHEMAS: dict[str, str] = {
    "fit": "bondid.fit",
    "sensitivity": "bondid.sensitivity",
    "diagnosis": "bondid.diagnose",
    "modes": "bondid.modes",
    "fleet": "bondid.fleet",
}

_MARKER = re.compile(
    r"<!--\s*bondid:(cli|schema|exceptions|study-example)\s*([A-Za-z0-9_.-]*)\s*-->"
)


class _Captured(BaseException):
    """Raised from ``parse_args`` to hand the parser back (a BaseException, so no
    ``except Exception`` or ``except SystemExit`` in a command's ``main`` swallows it)."""

    def __init__(self, parser: argparse.ArgumentParser) -> None:
        super().__init__("parser captured")
        self.parser = parser


def command_parser(name: str) -> argparse.ArgumentParser:
    """The argparse parser that ``python -m bondid.<name>`` uses.

    Raises:
        KeyError: ``name`` is not a command of :data:`COMMANDS`.
        RuntimeError: the command's ``main`` never parsed its arguments.
    """
    if name not in COMMANDS:
        raise KeyError(f"unknown command {name!r}; known: {', '.join(COMMANDS)}")
    main = _main_of(name)
    original = argparse.ArgumentParser.parse_args, argparse.ArgumentParser.parse_known_args

    def capture(self: argparse.ArgumentParser, *args: Any, **kwargs: Any) -> Any:
        raise _Captured(self)

    argparse.ArgumentParser.parse_args = capture  # type: ignore[method-assign,assignment]
    argparse.ArgumentParser.parse_known_args = capture  # type: ignore[method-assign,assignment]
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            main(["--help"])
    except _Captured as got:
        return got.parser
    finally:
        argparse.ArgumentParser.parse_args, argparse.ArgumentParser.parse_known_args = original
    raise RuntimeError(f"python -m bondid.{name}: its main() parsed no arguments")


def _main_of(name: str) -> Any:
    for module in (f"bondid.{name}.__main__", f"bondid.{name}"):
        try:
            mod = importlib.import_module(module)
        except ModuleNotFoundError as exc:
            if exc.name is not None and not module.startswith(exc.name):
                raise  # a dependency of the command is missing: say so
            continue
        if callable(getattr(mod, "main", None)):
            return mod.main
    raise RuntimeError(f"python -m bondid.{name}: no main() found")


def _cell(text: str) -> str:
    """Text safe inside a Markdown table cell."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _default(action: argparse.Action) -> str:
    if isinstance(action, argparse._StoreTrueAction | argparse._StoreFalseAction):
        return "off" if action.default is False else "on"
    d = action.default
    if d is None or d is argparse.SUPPRESS or d == [] or isinstance(action, argparse._HelpAction):
        return ""
    if isinstance(d, tuple) and len(d) == 3 and all(isinstance(v, int | float) for v in d):
        return f"`{d[0]:g}:{d[1]:g}:{d[2]:g}`"  # a F_LO:F_HI:N frequency grid
    if isinstance(d, list | tuple):
        return "`" + " ".join(str(v) for v in d) + "`"
    return f"`{d}`"


def _argument(action: argparse.Action) -> str:
    if action.nargs == 0:
        return ""
    if action.choices is not None:
        return " \\| ".join(f"`{c}`" for c in action.choices)
    metavar = action.metavar or (action.dest.upper() if action.option_strings else action.dest)
    if isinstance(metavar, tuple):
        metavar = " ".join(metavar)
    more = {"+": " …", "*": " …", "?": " (optional)"}.get(str(action.nargs), "")
    return f"`{metavar}`{more}"


def _help(action: argparse.Action, prog: str) -> str:
    text = action.help or ""
    if text is argparse.SUPPRESS:
        return ""
    if "%" in text:
        params = {k: v for k, v in vars(action).items() if v is not argparse.SUPPRESS}
        params["prog"] = prog
        with contextlib.suppress(KeyError, ValueError, TypeError):
            text = text % params
    extra = []
    if action.required and action.option_strings:
        extra.append("**required**")
    repeatable = isinstance(action, argparse._AppendAction | argparse._ExtendAction)
    if repeatable and "repeatable" not in text:
        extra.append("repeatable")
    return _cell(" ".join([text, *(f"({e})" for e in extra)]))


def cli_markdown(name: str) -> str:
    """The usage line, description and an options table per group of ``bondid.<name>``."""
    p = command_parser(name)
    usage = " ".join(p.format_usage().split())
    if usage.startswith("usage: "):
        usage = usage[len("usage: ") :]
    lines = [f"```text\n{usage}\n```", "", _cell(p.description or COMMANDS[name]), ""]
    for group in p._action_groups:
        actions = [a for a in group._group_actions if a.help is not argparse.SUPPRESS]
        if not actions:
            continue
        title = group.title or "options"
        lines += [f"**{title[:1].upper() + title[1:]}**", ""]
        lines += ["| option | argument | default | what it does |", "|---|---|---|---|"]
        for a in actions:
            names = ", ".join(f"`{s}`" for s in a.option_strings) or f"`{a.dest}`"
            lines.append(f"| {names} | {_argument(a)} | {_default(a)} | {_help(a, p.prog)} |")
        lines.append("")
    return "\n".join(lines)


def load_schema(name: str) -> dict[str, Any]:
    """The JSON Schema of ``<name>.json`` shipped in the package."""
    if name not in SCHEMAS:
        raise KeyError(f"unknown result file {name!r}; known: {', '.join(SCHEMAS)}")
    text = resources.files("bondid.schemas").joinpath(f"{name}.schema.json").read_text("utf-8")
    schema: dict[str, Any] = json.loads(text)
    return schema


def _resolve(node: dict[str, Any], root: dict[str, Any]) -> dict[str, Any]:
    ref = node.get("$ref")
    if isinstance(ref, str) and ref.startswith("#/$defs/"):
        target = root["$defs"][ref.split("/")[-1]]
        merged = {**target, **{k: v for k, v in node.items() if k != "$ref"}}
        return merged
    return node


def _type_of(node: dict[str, Any], root: dict[str, Any]) -> str:
    node = _resolve(node, root)
    if "enum" in node:
        return " \\| ".join(f"`{json.dumps(v)}`" for v in node["enum"])
    if "const" in node:
        return f"`{json.dumps(node['const'])}`"
    for key in ("anyOf", "oneOf"):
        if key in node:
            return " or ".join(_type_of(n, root) for n in node[key])
    t = node.get("type", "any")
    if isinstance(t, list):
        return " or ".join(t)
    if t == "array" and isinstance(node.get("items"), dict):
        inner = _resolve(node["items"], root)
        return f"array of {inner.get('title') or _type_of(inner, root)}"
    if t == "object" and isinstance(node.get("additionalProperties"), dict):
        inner = node["additionalProperties"]
        return f"object: name → {_type_of(inner, root)}"
    return str(t)


def _walk(
    node: dict[str, Any], root: dict[str, Any], path: str, rows: list[str], seen: set[str]
) -> None:
    node = _resolve(node, root)
    props = node.get("properties")
    if not isinstance(props, dict):
        items = node.get("items")
        if isinstance(items, dict):
            _walk(items, root, path + "[]", rows, seen)
        extra = node.get("additionalProperties")
        if isinstance(extra, dict) and path:
            _walk(extra, root, path + ".*", rows, seen)
        return
    required = set(node.get("required", ()))
    for key, sub in props.items():
        full = f"{path}.{key}" if path else key
        sub_r = _resolve(sub, root)
        mark = " **(required)**" if key in required else ""
        desc = _cell(sub_r.get("description", ""))
        rows.append(f"| `{full}` | {_cell(_type_of(sub, root))} | {desc}{mark} |")
        ref = sub.get("$ref") or (sub.get("items") or {}).get("$ref")
        if ref:
            if ref in seen:
                continue
            seen = seen | {ref}
        _walk(sub, root, full, rows, seen)


def schema_markdown(name: str) -> str:
    """A table of every key of ``<name>.json`` (dotted paths, ``[]`` for list items)."""
    schema = load_schema(name)
    rows = ["| key | type | meaning |", "|---|---|---|"]
    _walk(schema, schema, "", rows, set())
    head = _cell(schema.get("description", ""))
    src = (
        f"Schema: `bondid/schemas/{name}.schema.json` (JSON Schema 2020-12, shipped in the"
        " package)."
    )
    return "\n".join([head, "", src, "", *rows, ""])


def exceptions_markdown() -> str:
    """The tree of :mod:`bondid.exceptions` with each class's builtin base and docstring."""
    from bondid import exceptions

    root = exceptions.BondidError
    classes = {
        c
        for c in vars(exceptions).values()
        if isinstance(c, type) and issubclass(c, root) and c.__module__ == exceptions.__name__
    }
    lines: list[str] = []

    def visit(cls: type, depth: int) -> None:
        builtins = [b.__name__ for b in cls.__bases__ if b.__module__ == "builtins"]
        also = f" (also `{'`, `'.join(builtins)}`)" if builtins and cls is not root else ""
        doc = " ".join((cls.__doc__ or "").split()).replace("``", "`")
        lines.append(f"{'    ' * depth}- `{cls.__name__}`{also}: {doc}")
        for sub in sorted((c for c in classes if cls in c.__bases__), key=lambda c: c.__name__):
            visit(sub, depth + 1)

    visit(root, 0)
    return "\n".join(lines) + "\n"


def study_example() -> str:
    """The annotated TOML example of :mod:`bondid.fit.study`'s docstring, as a code block."""
    from bondid.fit import study

    doc = study.__doc__ or ""
    _, sep, rest = doc.partition("::\n")
    if not sep:
        raise RuntimeError("bondid.fit.study: its docstring has no example block")
    lines = []
    for line in rest.splitlines():
        if line.strip() and not line.startswith("    "):
            break
        lines.append(line[4:])
    return "```toml\n" + "\n".join(lines).strip("\n") + "\n```\n"


def render(markdown: str) -> str:
    """``markdown`` with every marker replaced by its generated text."""

    def one(m: re.Match[str]) -> str:
        kind, name = m.group(1), m.group(2)
        if kind == "cli":
            return cli_markdown(name)
        if kind == "schema":
            return schema_markdown(name)
        if kind == "study-example":
            return study_example()
        return exceptions_markdown()

    return _MARKER.sub(one, markdown)


def on_page_markdown(markdown: str, **kwargs: Any) -> str:
    """MkDocs event: fill the markers of every page."""
    return render(markdown)

"""The generated reference: every command has a page whose options come from its own parser,
every result file a page from its schema, and the package's version is the project's."""

from __future__ import annotations

import argparse
import importlib.util
import json
import re
import sys
import tomllib
from importlib import metadata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "bondid"
DOCS = ROOT / "docs"


def _hook():
    spec = importlib.util.spec_from_file_location("bondid_docs", DOCS / "hooks" / "bondid_docs.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["bondid_docs"] = mod
    spec.loader.exec_module(mod)
    return mod


hook = _hook()


def package_commands() -> set[str]:
    """Every ``python -m bondid.<command>`` of the source tree: sub-packages with a
    ``__main__.py`` and top-level modules that run as a script."""
    found = {p.parent.name for p in SRC.glob("*/__main__.py")}
    for p in SRC.glob("*.py"):
        if p.stem != "__main__" and '__name__ == "__main__"' in p.read_text(encoding="utf-8"):
            found.add(p.stem)
    return found


def test_every_command_has_a_reference_page():
    assert package_commands() == set(hook.COMMANDS)
    for name in hook.COMMANDS:
        page = (DOCS / "reference" / "commands" / f"{name}.md").read_text(encoding="utf-8")
        assert f"<!-- bondid:cli {name} -->" in page, name


@pytest.mark.parametrize("name", list(hook.COMMANDS))
def test_the_page_lists_every_option_of_the_parser(name):
    parser = hook.command_parser(name)
    assert isinstance(parser, argparse.ArgumentParser)
    text = hook.cli_markdown(name)
    options = [s for a in parser._actions for s in a.option_strings if a.help != argparse.SUPPRESS]
    assert options
    for opt in options:
        assert f"`{opt}`" in text, (name, opt)


def test_every_schema_has_a_page_and_every_key_a_row():
    for name in hook.SCHEMAS:
        page = (DOCS / "reference" / "outputs" / f"{name}.md").read_text(encoding="utf-8")
        assert f"<!-- bondid:schema {name} -->" in page, name
        schema = hook.load_schema(name)
        table = hook.schema_markdown(name)
        for key in schema["properties"]:
            assert f"| `{key}` |" in table, (name, key)


def test_markers_are_replaced_and_unknown_ones_refused():
    text = hook.render("<!-- bondid:exceptions -->\n<!-- bondid:study-example -->")
    assert "`BondidError`" in text and "`ConfigError` (also `ValueError`)" in text
    assert text.count("```toml") == 1 and "[parameters]" in text
    with pytest.raises(KeyError):
        hook.render("<!-- bondid:cli no_such_command -->")
    with pytest.raises(KeyError):
        hook.render("<!-- bondid:schema no_such_file -->")


def test_every_page_of_the_nav_exists():
    nav = re.findall(r":\s*([\w/.-]+\.md)\s*$|^\s*-\s+([\w/.-]+\.md)\s*$",
                     (ROOT / "mkdocs.yml").read_text(encoding="utf-8"), flags=re.M)  # fmt: skip
    pages = [a or b for a, b in nav]
    assert len(pages) > 30
    for p in pages:
        assert (DOCS / p).is_file(), p


def test_the_version_is_the_projects():
    import bondid

    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert re.fullmatch(r"\d+\.\d+\.\d+", bondid.__version__)
    # the fallback of a source tree without an install is the project's version too
    init = (SRC / "__init__.py").read_text(encoding="utf-8")
    assert re.search(r'__version__ = "([^"]+)"', init).group(1) == project["version"]
    try:
        dist = metadata.distribution("bondid")
        direct = json.loads(dist.read_text("direct_url.json") or "{}")
    except metadata.PackageNotFoundError:
        direct = {}
    url = str(direct.get("url", ""))
    if not url.startswith("file://") or Path(url[7:]).resolve() != ROOT.resolve():
        pytest.skip("bondid is not installed from this tree (its metadata is another's)")
    assert bondid.__version__ == project["version"]


def test_the_schemas_and_py_typed_are_package_data():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    data = project["tool"]["setuptools"]["package-data"]["bondid"]
    assert "py.typed" in data and "schemas/*.schema.json" in data
    assert (SRC / "py.typed").is_file()
    assert len(list((SRC / "schemas").glob("*.schema.json"))) == len(hook.SCHEMAS)

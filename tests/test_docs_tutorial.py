"""Every command of the tutorial and of the README, run as a reader runs it.

The ``bash`` blocks of ``docs/tutorial/*.md`` and ``README.md`` are read from the Markdown;
each ``python -m bondid.…`` line runs, in the order the pages give them, from a folder that
holds copies of the repository's ``urdf/`` and ``data/`` (the commands name them relative to
the repository's top folder), and must exit 0. The set-up lines (the virtual environment,
``pip install``, the test command) are what the continuous integration itself runs; they
are recognised, not run. A line that is neither fails the test, so a new command in the
docs cannot go untested. The JSON files the commands write are then checked against the
schemas shipped in the package, and the report must exist.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the tutorial's pages in reading order, then the README
PAGES = [
    *(ROOT / "docs" / "tutorial" / f"{p}.md" for p in ("install", "fit", "sensitivity")),
    *(ROOT / "docs" / "tutorial" / f"{p}.md" for p in ("diagnose", "modes-report")),
    ROOT / "README.md",
]
#: set-up steps the CI runs itself (.ci/run): recognised, not run here
SETUP = (
    re.compile(r"^python3(\.\d+)? -m venv \.venv$"),
    re.compile(r"^\. \.venv/bin/activate$"),
    re.compile(r"^pip install -e (\.|'\.\[(test|docs)\]')$"),
    re.compile(r"^python -m pytest( -q)?( -n auto)?( -m (\"not slow\"|slow))?$"),
)
#: what the commands must write (relative to the run folder) and the schema of each JSON
OUTPUTS = {
    "results/fit.json": "fit",
    "results/sens/sensitivity.json": "sensitivity",
    "results/diag/diagnosis.json": "diagnosis",
    "results/modes/modes.json": "modes",
}
TIMEOUT_S = 1800


def bash_blocks(path: Path) -> list[str]:
    """The ``bash`` code blocks of a Markdown file, in order."""
    text = path.read_text(encoding="utf-8")
    return re.findall(r"^```bash\n(.*?)^```", text, flags=re.S | re.M)


def commands(block: str) -> list[str]:
    """The commands of a block: continuation lines joined, ``&&`` chains split, comments
    and blank lines dropped."""
    joined = re.sub(r"\s*\\\n\s*", " ", block)
    out = []
    for line in joined.splitlines():
        line = line.split(" #", 1)[0].strip()
        if line and not line.startswith("#"):
            out += [part.strip() for part in line.split("&&")]
    return out


def tutorial_commands() -> list[str]:
    """Every command of the pages, each once, in the order first given."""
    seen: list[str] = []
    for page in PAGES:
        for block in bash_blocks(page):
            for cmd in commands(block):
                if cmd not in seen:
                    seen.append(cmd)
    return seen


def is_setup(cmd: str) -> bool:
    return any(p.match(cmd) for p in SETUP)


def test_the_pages_have_commands_and_nothing_unknown():
    cmds = tutorial_commands()
    runnable = [c for c in cmds if not is_setup(c)]
    assert any(c.startswith("python3 -m venv") for c in cmds)  # the install is shown
    unknown = [c for c in runnable if not c.startswith("python -m bondid.")]
    assert not unknown, f"commands the test can neither run nor recognise: {unknown}"
    names = [c.split()[2] for c in runnable]
    for command in ("bondid.fit", "bondid.sensitivity", "bondid.diagnose", "bondid.modes"):
        assert command in names
    assert names[-1] == "bondid.report"  # the report gathers what the others wrote


def test_commands_are_split_and_joined():
    block = "a \\\n  b && c  # why\n# comment\n\nd\n"
    assert commands(block) == ["a b", "c", "d"]


def test_every_tutorial_command_runs(tmp_path):
    for folder in ("urdf", "data"):
        shutil.copytree(ROOT / folder, tmp_path / folder)
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    for cmd in tutorial_commands():
        if is_setup(cmd):
            continue
        argv = [sys.executable, *shlex.split(cmd)[1:]]
        p = subprocess.run(
            argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=TIMEOUT_S
        )
        assert p.returncode == 0, f"{cmd}: exit {p.returncode}\n{p.stderr[-3000:]}"
    from test_schemas import check

    for rel, name in OUTPUTS.items():
        check(name, tmp_path / rel)
    assert (tmp_path / "results" / "report.html").stat().st_size > 0
    # the tutorial's verdict on the bundled data: nothing is missing
    import json

    diag = json.loads((tmp_path / "results/diag/diagnosis.json").read_text(encoding="utf-8"))
    assert diag["verdict"]["effect"] == "none"
    assert diag["verdict"]["outcome"] == "explained"

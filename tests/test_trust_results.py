"""Results are written and cleaned only inside ``--out``, by names the run produced; a
manifest found in a folder is untrusted data; replacing a run's files is all or nothing,
also when the process is killed in the middle (issue 61)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bondid.exceptions import ManifestError
from bondid.journal import pending, recover
from bondid.manifest import RESULT_PATTERNS, read_manifest
from bondid.results import open_results

FIT = RESULT_PATTERNS["fit"]


def _run(out: Path, files: dict[str, str], command: str = "fit") -> None:
    """One complete run of ``command`` into ``out`` writing ``files``."""
    res = open_results(out, command, [], patterns=RESULT_PATTERNS[command])
    for name, text in files.items():
        res.path(name).write_text(text)
    res.commit(main=next(iter(files)))


def _snapshot(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): (
            f"-> {os.readlink(p)}" if p.is_symlink() else p.read_text() if p.is_file() else "/"
        )
        for p in sorted(folder.rglob("*"))
    }


def _plant(out: Path, command: str, entries: list[dict]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{command}.manifest.json").write_text(json.dumps({"files": entries}))


@pytest.mark.parametrize(
    "name",
    ["../victim.txt", "/ABS/victim.txt", "sub/../../victim.txt", "notes.txt", ".hidden.png",
     "..", "", "fit.json/..", "bode_\0.png"],
)  # fmt: skip
def test_a_planted_manifest_never_deletes_anything(tmp_path, name):
    """The issue's attack: the previous run's manifest names files outside --out, or a file
    of the user's that no run writes; the next run is refused, exit 2, nothing touched."""
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("the user's")
    name = name.replace("/ABS", str(tmp_path))
    _plant(out, "fit", [{"name": name, "bytes": 4, "sha256": "0"}])
    before = _snapshot(tmp_path)
    with pytest.raises(ManifestError, match="files entry 1"):
        open_results(out, "fit", [], patterns=FIT)
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize(
    "content",
    ["[1, 2, 3]", "{not json", '{"files": {"name": "fit.json"}}', '{"files": [3]}',
     '{"files": [{"name": "fit.json", "bytes": "2", "sha256": "0"}]}',
     '{"files": [{"name": "fit.json", "bytes": 2, "sha256": null}]}',
     '{"files": [], "warnings": "x"}'],
)  # fmt: skip
def test_a_malformed_manifest_refuses_the_run(tmp_path, content):
    out = tmp_path / "out"
    out.mkdir()
    (out / "fit.json").write_text("old")
    (out / "fit.manifest.json").write_text(content)
    before = _snapshot(tmp_path)
    with pytest.raises(ManifestError):
        open_results(out, "fit", [], patterns=FIT)
    assert _snapshot(tmp_path) == before


def test_a_manifest_that_is_a_link_or_fifo_is_refused_unread(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    secret = tmp_path / "secret.json"
    secret.write_text('{"files": []}')
    (out / "fit.manifest.json").symlink_to(secret)
    with pytest.raises(ManifestError, match="not a regular file"):
        open_results(out, "fit", [], patterns=FIT)
    (out / "fit.manifest.json").unlink()
    os.mkfifo(out / "fit.manifest.json")  # reading it would block for good
    with pytest.raises(ManifestError, match="not a regular file"):
        read_manifest(out, "fit")


def test_links_inside_out_pointing_out_are_replaced_not_followed(tmp_path):
    """A result name that is a link to a file outside: the run replaces the link itself;
    the target keeps its content. A listed file that is a link does not verify."""
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    out = tmp_path / "out"
    _run(out, {"fit.json": "1", "bode_a.png": "a"})
    (out / "bode_a.png").unlink()
    (out / "bode_a.png").symlink_to(victim)  # a stale name of the old run, now a link
    with pytest.raises(ManifestError, match="differs"):
        read_manifest(out, "fit")
    (out / "fit.json").unlink()
    (out / "fit.json").symlink_to(victim)
    _run(out, {"fit.json": "2"})
    assert victim.read_text() == "keep"
    assert not (out / "fit.json").is_symlink() and (out / "fit.json").read_text() == "2"
    assert not os.path.lexists(out / "bode_a.png")  # the link (not its target) removed
    assert sorted(os.listdir(out)) == ["fit.json", "fit.manifest.json"]


def test_a_planted_lock_link_is_refused_without_truncating_its_target(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    (tmp_path / ".out.bondid-lock").symlink_to(victim)
    with pytest.raises(Exception, match="symbolic link"):
        open_results(tmp_path / "out", "fit", [], patterns=FIT)
    assert victim.read_text() == "keep"


def test_only_the_runs_own_staging_folders_are_cleaned(tmp_path):
    """Stale staging folders match ``.<out>.bondid-tmp-<pid>-<8 hex>``; a user's folder of
    a similar name, or a link of that name, is left alone."""
    keep = tmp_path / ".out.bondid-tmp-mine"
    keep.mkdir()
    (keep / "x").write_text("user")
    target = tmp_path / "elsewhere"
    target.mkdir()
    (target / "y").write_text("user")
    (tmp_path / ".out.bondid-tmp-1-deadbeef").symlink_to(target)
    stale = tmp_path / ".out.bondid-tmp-2-cafebabe"
    stale.mkdir()
    open_results(tmp_path / "out", "fit", [], patterns=FIT).close()
    assert (keep / "x").exists() and (target / "y").exists() and not stale.exists()


# -- a kill during the commit ---------------------------------------------------------------

KILL = """
import os, sys
from pathlib import Path
from bondid import journal
from bondid.results import open_results

out, after = Path(sys.argv[1]), int(sys.argv[2])
moved = [0]
real = journal.move

def move(src, dst):
    real(src, dst)
    moved[0] += 1
    if moved[0] == after:
        os._exit(9)  # as SIGKILL: no clean-up runs

journal.move = move
res = open_results(out, "fit", [], patterns=("fit.json", "fitted.urdf", "bode_*.png",
                                            "convergence.png"))
res.path("fit.json").write_text("new")
res.path("bode_q0.png").write_text("new q0")
res.commit(main="fit.json")
"""


def _killed_commit(out: Path, after: int) -> int:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    return subprocess.run(
        [sys.executable, "-c", KILL, str(out), str(after)], env=env, timeout=60
    ).returncode


OLD = {"fit.json": "old", "bode_q0.png": "old q0", "bode_q1.png": "old q1",
       "convergence.png": "old conv"}  # fmt: skip


@pytest.mark.parametrize("after", [1, 2])
def test_a_kill_in_the_middle_of_a_commit_is_undone(tmp_path, after):
    """The issue's case: killed after the new fit.json (and bode_q0.png) moved in, beside
    the old plots. A reader sees no complete run; the next run into the folder puts the
    previous run back, whole."""
    out = tmp_path / "out"
    _run(out, OLD)
    (out / "notes.txt").write_text("the user's")
    old = _snapshot(out)
    assert _killed_commit(out, after) == 9
    assert (out / "fit.json").read_text() == "new"  # half-replaced ...
    assert read_manifest(out, "fit") is None  # ... and no complete run to read
    assert pending(out) == ["fit"]
    assert recover(out, "fit") == "undone"
    assert _snapshot(out) == old
    assert read_manifest(out, "fit") is not None


def test_a_kill_after_the_new_manifest_keeps_the_new_run(tmp_path):
    out = tmp_path / "out"
    _run(out, OLD)
    assert _killed_commit(out, 3) == 9  # fit.json, bode_q0.png, then the manifest moved
    assert pending(out) == ["fit"]
    open_results(out, "fit", [], patterns=FIT).close()  # the next run finishes it
    assert pending(out) == []
    assert sorted(os.listdir(out)) == ["bode_q0.png", "fit.json", "fit.manifest.json"]
    assert read_manifest(out, "fit") is not None


def test_report_refuses_or_restores_a_half_replaced_folder(tmp_path, capsys):
    from bondid.report.__main__ import main as report

    out = tmp_path / "out"
    _run(out, {"fit.json": json.dumps({"status": "old", "parameters": []})})
    (out / "bode_q1.png").write_bytes(b"")
    _run(out, {"fit.json": json.dumps({"status": "old", "parameters": []}), "bode_q1.png": ""})
    assert _killed_commit(out, 1) == 9
    assert report([str(out), "--out", str(tmp_path / "elsewhere")]) == 2
    err = capsys.readouterr().err
    assert "interrupted" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "elsewhere").exists()
    assert report([str(out), "--quiet"]) == 0  # writing into it: restores first
    assert json.loads((out / "fit.json").read_text())["status"] == "old"
    assert "restored" in capsys.readouterr().err


def test_report_warns_on_files_without_or_outside_their_manifest(tmp_path, capsys):
    from bondid.report.__main__ import main as report

    out = tmp_path / "r"
    _run(out, {"fit.json": json.dumps({"status": "s", "parameters": []})})
    (out / "bode_q1.png").write_bytes(b"")  # not in the manifest: another run's
    assert report([str(out), "--quiet"]) == 0
    assert "bode_q1.png not listed in fit.manifest.json" in capsys.readouterr().err
    (out / "fit.manifest.json").unlink()
    assert report([str(out), "--quiet"]) == 0
    assert "no fit.manifest.json beside it" in capsys.readouterr().err
    page = (out / "report.html").read_text()
    assert "no fit.manifest.json beside it" in page


def test_a_full_disk_while_writing_the_journal_leaves_the_previous_run(tmp_path, monkeypatch):
    import errno

    from bondid import journal

    out = tmp_path / "out"
    _run(out, OLD)
    old = _snapshot(out)

    def full(undo, record):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(journal, "_write_journal", full)
    res = open_results(out, "fit", [], patterns=FIT)
    res.path("fit.json").write_text("new")
    with pytest.raises(OSError):
        res.commit()
    res.close()
    assert _snapshot(out) == old
    assert os.listdir(tmp_path) == ["out"]


def test_every_command_writes_only_its_registered_names():
    """The manifest registry and each command's own output names agree."""
    from bondid.diagnose.cli import OUT_PATTERNS as DIAGNOSE
    from bondid.fit.cli import OUT_PATTERNS as FIT_NAMES
    from bondid.modes.__main__ import OUT_PATTERNS as MODES
    from bondid.report.build import REPORT_NAME
    from bondid.sensitivity.output import PNG_NAMES

    assert set(RESULT_PATTERNS["fit"]) == set(FIT_NAMES)
    assert set(RESULT_PATTERNS["diagnose"]) == set(DIAGNOSE)
    assert set(RESULT_PATTERNS["modes"]) == set(MODES)
    assert RESULT_PATTERNS["report"] == (REPORT_NAME,)
    assert set(RESULT_PATTERNS["sensitivity"]) == {"sensitivity.json", *PNG_NAMES.values()}

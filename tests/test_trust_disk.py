"""A full disk: exit 1 with one line "no space left writing DIR; the previous results are
intact", and they are (issue 61)."""

from __future__ import annotations

import errno
import json
import os
import subprocess

import pytest
from trust_common import fast_argv, make_inputs, only_line, runner


@pytest.fixture(scope="module")
def trust_inputs(tmp_path_factory):
    return make_inputs(tmp_path_factory)


@pytest.fixture
def run_cmd(capsys):
    return runner(capsys)


def _snapshot(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def test_no_space_while_writing_keeps_the_previous_results(trust_inputs, run_cmd, tmp_path,
                                                           monkeypatch):  # fmt: skip
    """ENOSPC from the writer (injected): one line naming --out, the old run intact."""
    from bondid import atomic

    out = tmp_path / "out"
    code, _, err = run_cmd("modes", *fast_argv("modes", trust_inputs["model"], None, out))
    assert code == 0, err
    before = _snapshot(out)

    def full(path, text):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(atomic, "write_text_atomic", full)
    code, _, err = run_cmd("modes", *fast_argv("modes", trust_inputs["model"], None, out))
    line = only_line(err)
    assert code == 1
    assert line == f"error: no space left writing {out}; the previous results are intact"
    assert _snapshot(out) == before
    assert sorted(os.listdir(tmp_path)) == ["out"]  # no staging folder, no lock


@pytest.fixture
def tiny_disk(tmp_path):
    """A 256 kB tmpfs (needs root and mount rights; skipped elsewhere)."""
    mnt = tmp_path / "disk"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mnt)],
                       capture_output=True)  # fmt: skip
    if r.returncode != 0:
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def test_a_really_full_disk(trust_inputs, run_cmd, tiny_disk):
    """The whole path on a real full file system: modes.json fits, then the disk is filled
    and fit (plots of tens of kB) runs into it."""
    out = tiny_disk / "out"
    code, _, err = run_cmd("modes", *fast_argv("modes", trust_inputs["model"], None, out))
    assert code == 0, err
    before = _snapshot(out)
    filler = tiny_disk / "filler"
    st = os.statvfs(tiny_disk)
    with open(filler, "wb", buffering=0) as fh:  # leave about 24 kB: a start, not a run
        fh.write(b"\0" * max(0, st.f_bavail * st.f_frsize - 24 * 1024))
    for command in ("modes", "fit"):
        argv = fast_argv(command, trust_inputs["model"], trust_inputs["data"], out)
        code, _, err = run_cmd(command, *argv)
        line = only_line(err)
        assert code == 1 and line == (
            f"error: no space left writing {out}; the previous results are intact"
        ), err
        assert _snapshot(out) == before
        assert sorted(os.listdir(tiny_disk)) == ["filler", "out"]
    assert json.loads((out / "modes.json").read_text())["modes"]

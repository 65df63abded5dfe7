"""Property-based fuzzing of the readers of untrusted files (issue 61): measured data (CSV
and UFF58), URDF models and results manifests. Whatever the bytes, a reader returns a valid
object or raises bondid's own error (exit 2 on the command line) — never another exception,
never a hang, never a file touched outside the results folder."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bondid.exceptions import BondidError, ManifestError
from bondid.manifest import RESULT_PATTERNS, parse_manifest, valid_name
from bondid.paths import plain_name

REPO = Path(__file__).resolve().parents[1]
BONDER_TEXT = (REPO / "urdf" / "bonder.urdf").read_text()
FUZZ = settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow],
    derandomize=True,
)  # fmt: skip

#: cell contents that broke or nearly broke readers: empty, non-numbers, extremes, quotes
TOKENS = ["", "nan", "NaN", "inf", "-inf", "1e300", "-1e-300", "1e-320", "abc", "0", "-0",
          "1,2", '"', "'", "\x00", "1e999", "0x10", "  7 ", "１", "#", "x.x.re",
          "\ufeff"]  # fmt: skip


def _small_data():
    from bondid.model.document import UrdfDocument
    from bondid.simulate import log_grid, simulate

    return simulate(UrdfDocument.from_string(BONDER_TEXT), {}, log_grid(5.0, 3000.0, 6),
                    noise=0.02, seed=1)  # fmt: skip


@pytest.fixture(scope="module")
def valid_files(tmp_path_factory) -> dict[str, bytes]:
    from bondid.data.io import write_frf

    root = tmp_path_factory.mktemp("fuzz")
    ds = _small_data()
    write_frf(ds, root / "d.csv")
    write_frf(ds, root / "d.uff")
    return {"csv": (root / "d.csv").read_bytes(), "uff": (root / "d.uff").read_bytes()}


def _read(raw: bytes, suffix: str) -> None:
    """Read ``raw`` as a data file of ``suffix``: a FrfData that passes or fails the value
    checks with a DataError, or a bondid error while reading."""
    from bondid.data.io import read_frf
    from bondid.validation.data import check_values

    folder = Path(tempfile.mkdtemp(prefix="bondid-fuzz-"))
    try:
        path = folder / f"f{suffix}"
        path.write_bytes(raw)
        try:
            ds = read_frf(path)
        except BondidError:
            return
        assert ds.H.ndim == 3 and ds.H.shape[2] == ds.freq_hz.size
        assert np.all(np.diff(ds.freq_hz) > 0) and np.all(ds.freq_hz > 0)
        with contextlib.suppress(BondidError):
            check_values(ds)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@st.composite
def mutated_lines(draw, text: str) -> bytes:
    """``text`` with a few line-level edits: a cell replaced by a token or a random number,
    a line deleted or repeated, the file cut short."""
    lines = text.split("\n")
    for _ in range(draw(st.integers(1, 4))):
        k = draw(st.integers(0, len(lines) - 1))
        what = draw(st.sampled_from(["cell", "delete", "repeat", "cut", "swap"]))
        if what == "cell":
            cells = lines[k].split(",")
            j = draw(st.integers(0, len(cells) - 1))
            cells[j] = draw(st.one_of(st.sampled_from(TOKENS), st.floats().map(repr),
                                      st.text(max_size=6)))  # fmt: skip
            lines[k] = ",".join(cells)
        elif what == "delete" and len(lines) > 1:
            del lines[k]
        elif what == "repeat":
            lines.insert(k, lines[k])
        elif what == "cut":
            lines[k] = lines[k][: draw(st.integers(0, len(lines[k])))]
            lines = lines[: k + 1]
        elif what == "swap" and len(lines) > 1:
            j = draw(st.integers(0, len(lines) - 1))
            lines[k], lines[j] = lines[j], lines[k]
    return "\n".join(lines).encode("utf-8", errors="surrogatepass")


@FUZZ
@given(raw=st.binary(max_size=400))
def test_csv_reader_on_any_bytes(raw):
    _read(raw, ".csv")


@FUZZ
@given(data=st.data())
def test_csv_reader_on_mutated_files(valid_files, data):
    _read(data.draw(mutated_lines(valid_files["csv"].decode())), ".csv")


@st.composite
def mutated_bytes(draw, raw: bytes) -> bytes:
    """``raw`` with a few bytes replaced, a span deleted or the file cut short."""
    b = bytearray(raw)
    for _ in range(draw(st.integers(1, 4))):
        if not b:
            break
        k = draw(st.integers(0, len(b) - 1))
        what = draw(st.sampled_from(["byte", "digit", "delete", "cut"]))
        if what == "byte":
            b[k] = draw(st.integers(0, 255))
        elif what == "digit":
            b[k] = draw(st.sampled_from(b"0123456789-+.eE "))
        elif what == "delete":
            del b[k : k + draw(st.integers(1, 80))]
        else:
            del b[k:]
    return bytes(b)


@FUZZ
@given(data=st.data())
def test_uff_reader_on_mutated_files(valid_files, data):
    _read(data.draw(mutated_bytes(valid_files["uff"])), ".uff")


@FUZZ
@given(raw=st.binary(max_size=400))
def test_uff_reader_on_any_bytes(raw):
    _read(raw, ".uff")


# -- URDF ------------------------------------------------------------------------------------

#: attribute values that broke or nearly broke the model readers
URDF_TOKENS = ["", "nan", "inf", "-inf", "1e300", "-1e300", "1e-300", "0", "-1", "abc",
               "1 2", "1 2 3 4", "0 0 0", "&amp;", "x", "fixed", "floating", "planar"]  # fmt: skip


@st.composite
def mutated_urdf(draw) -> str:
    """The bonder with a few attribute values, element texts or whole elements changed."""
    import re

    text = BONDER_TEXT
    attrs = [m.span(1) for m in re.finditer(r'="([^"]*)"', text)]
    for _ in range(draw(st.integers(1, 3))):
        what = draw(st.sampled_from(["attr", "attr", "drop", "nest"]))
        if what == "attr":
            a, b = draw(st.sampled_from(attrs))
            value = draw(st.one_of(st.sampled_from(URDF_TOKENS), st.floats().map(repr)))
            text = text[:a] + value + text[b:]
        elif what == "drop":
            tags = [
                m.span()
                for m in re.finditer(
                    r"<(inertial|limit|axis|origin|mass|"
                    r"child|parent|joint)\b[^>]*/>",
                    text,
                )
            ]
            if tags:
                a, b = draw(st.sampled_from(tags))
                text = text[:a] + text[b:]
        else:
            depth = draw(st.sampled_from([5, 60, 150]))
            text = text.replace("</robot>", "<gazebo>" + "<a>" * depth + "</a>" * depth
                                + "</gazebo></robot>")  # fmt: skip
        attrs = [m.span(1) for m in re.finditer(r'="([^"]*)"', text)]
    return text


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow],
          derandomize=True)  # fmt: skip
@given(text=mutated_urdf())
def test_urdf_reader_and_checks_on_mutated_models(text):
    from bondid.model.document import UrdfDocument
    from bondid.validation.model import check_model

    try:
        doc = UrdfDocument.from_string(text, source="fuzz.urdf")
        check_model(doc)
    except BondidError as exc:
        assert "\n" not in " ".join(str(exc).split()), exc


@FUZZ
@given(text=st.text(max_size=300))
def test_urdf_reader_on_any_text(text):
    from bondid.model.document import UrdfDocument

    with contextlib.suppress(BondidError):
        UrdfDocument.from_string(text, source="fuzz.urdf")


# -- manifests -------------------------------------------------------------------------------

NAMES = st.one_of(
    st.sampled_from(["fit.json", "bode_q0.png", "fitted.urdf", "../victim.txt", "/etc/passwd",
                     "..", ".", "", "sub/fit.json", ".hidden.png", "notes.txt", "fit.json\0",
                     "bode_/../x.png", "C:\\x.png", "convergence.png"]),
    st.text(max_size=12),
)  # fmt: skip
JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=6), children, max_size=4)
    ),
    max_leaves=12,
)
ENTRY = st.fixed_dictionaries(
    {"name": NAMES},
    optional={"bytes": st.one_of(st.integers(-2, 99), st.text(max_size=3), st.none()),
              "sha256": st.one_of(st.text(max_size=8), st.none(), st.integers())},
)  # fmt: skip


@FUZZ
@given(doc=st.one_of(JSON, st.fixed_dictionaries({"files": st.lists(ENTRY, max_size=4)})))
def test_manifest_parser_accepts_only_plain_result_names(doc):
    text = json.dumps(doc)
    try:
        m = parse_manifest(text, "x/fit.manifest.json", "fit", RESULT_PATTERNS["fit"])
    except ManifestError:
        return
    for name in m["files_by_name"]:
        assert plain_name(name) and valid_name(name, RESULT_PATTERNS["fit"])


@settings(max_examples=40, deadline=None, derandomize=True)
@given(entries=st.lists(ENTRY, max_size=4))
def test_a_planted_manifest_never_touches_anything_outside_out(entries):
    """Plant any manifest into a results folder beside files outside and the user's own
    file inside; the next run either refuses (nothing touched) or runs, and everything
    outside ``--out`` and every non-result file inside stays as it was."""
    from bondid.results import open_results

    root = Path(tempfile.mkdtemp(prefix="bondid-fuzz-"))
    try:
        (root / "victim.txt").write_text("keep")
        out = root / "out"
        out.mkdir()
        (out / "notes.txt").write_text("the user's")
        (out / "fit.json").write_text("old")
        (out / "fit.manifest.json").write_text(json.dumps({"files": entries}))
        before = {p: p.read_bytes() for p in root.rglob("*") if p.is_file()}
        try:
            res = open_results(out, "fit", [], patterns=RESULT_PATTERNS["fit"])
        except ManifestError:
            after = {p: p.read_bytes() for p in root.rglob("*") if p.is_file()}
            assert after == before
            return
        res.path("fit.json").write_text("new")
        res.commit(main="fit.json")
        assert (root / "victim.txt").read_text() == "keep"
        assert (out / "notes.txt").read_text() == "the user's"
        assert sorted(os.listdir(root)) == ["out", "victim.txt"]
    finally:
        shutil.rmtree(root, ignore_errors=True)

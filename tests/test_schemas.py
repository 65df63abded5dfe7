"""The JSON Schemas shipped in ``bondid/schemas`` against real outputs of the commands.

Each command runs as a user runs it (``python -m bondid.<command>`` in a subprocess) on small
synthetic data of the reference bonder; its JSON must validate against the schema, and every
key it writes must be documented there (an object schema with ``properties`` and no explicit
``additionalProperties`` lists every key; ``additionalProperties: true`` marks an open object,
a schema there a map). So a new key without a line in the schema fails here, and the
reference pages, generated from the schemas, cannot fall behind the files.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

jsonschema = pytest.importorskip("jsonschema")

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "urdf" / "bonder.urdf"
SCHEMAS = ("fit", "sensitivity", "diagnosis", "modes", "fleet")
FREE = ["x_guide_ry.stiffness", "y_guide_rx.stiffness", "z.stiffness"]
#: a small grid: the commands' code paths are the same as on 2000 lines
FREQ = "1:4000:150"
TIMEOUT_S = 1800  # a guard against a hang, not a measure of time


def schema(name: str) -> dict[str, Any]:
    text = resources.files("bondid.schemas").joinpath(f"{name}.schema.json").read_text("utf-8")
    return json.loads(text)


def undocumented(instance: Any, node: dict[str, Any], root: dict[str, Any], path: str = "$"):
    """Paths of keys in ``instance`` that the schema ``node`` does not describe."""
    ref = node.get("$ref")
    if isinstance(ref, str):
        node = {**root["$defs"][ref.rsplit("/", 1)[-1]], **node}
    for key in ("anyOf", "oneOf"):
        if key in node:  # the first branch that validates describes the value
            for sub in node[key]:
                if jsonschema.Draft202012Validator(
                    {**sub, "$defs": root.get("$defs", {})}
                ).is_valid(instance):
                    yield from undocumented(instance, sub, root, path)
                    break
            return
    if isinstance(instance, dict):
        props = node.get("properties")
        extra = node.get("additionalProperties")
        for k, v in instance.items():
            if isinstance(props, dict) and k in props:
                yield from undocumented(v, props[k], root, f"{path}.{k}")
            elif isinstance(extra, dict):
                yield from undocumented(v, extra, root, f"{path}.{k}")
            elif isinstance(props, dict) and extra is None:
                yield f"{path}.{k}"
    elif isinstance(instance, list) and isinstance(node.get("items"), dict):
        for i, v in enumerate(instance):
            yield from undocumented(v, node["items"], root, f"{path}[{i}]")


def check(name: str, path: Path) -> dict[str, Any]:
    """Validate ``path`` against schema ``name``; every key documented."""
    s = schema(name)
    doc = json.loads(path.read_text(encoding="utf-8"))
    jsonschema.Draft202012Validator(s).validate(doc)
    missing = sorted(set(undocumented(doc, s, s)))
    assert not missing, (
        f"{path.name}: keys not described in src/bondid/schemas/{name}.schema.json: {missing}"
    )
    return doc


def run(*args: str, cwd: Path) -> None:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    cmd = [sys.executable, "-m", *args]
    p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
    assert p.returncode == 0, f"{' '.join(args)}: exit {p.returncode}\n{p.stderr[-3000:]}"


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("schemas")
    for name, q in (("q0.csv", []), ("q1.csv", ["--q", "x=0.05", "y=-0.03"])):
        run("bondid.simulate", "--model", str(MODEL), "--out", name, "--freq", FREQ, *q, cwd=d)
    return d


def test_every_schema_is_valid_and_shipped():
    files = {p.name for p in resources.files("bondid.schemas").iterdir()}
    assert {f"{n}.schema.json" for n in SCHEMAS} <= files
    for n in SCHEMAS:
        s = schema(n)
        jsonschema.Draft202012Validator.check_schema(s)
        assert s["$id"].endswith(f"/{n}.schema.json") and s["title"] == f"{n}.json"
        assert s["description"] and s["required"]


def test_undocumented_keys_are_found():
    s = {"type": "object", "properties": {"a": {"type": "object", "properties": {"b": {}}}}}
    assert list(undocumented({"a": {"b": 1, "c": 2}, "d": 3}, s, s)) == ["$.a.c", "$.d"]
    open_ = {"type": "object", "properties": {"a": {}}, "additionalProperties": True}
    assert list(undocumented({"a": 1, "z": 2}, open_, open_)) == []


@pytest.mark.smoke
def test_fit_json(data):
    run("bondid.fit", "--model", str(MODEL), "--data", "q0.csv", "q1.csv", "--free", *FREE,
        "--out", "fit", "--quiet", cwd=data)  # fmt: skip
    doc = check("fit", data / "fit" / "fit.json")
    assert [p["name"] for p in doc["parameters"]] == FREE


def test_sensitivity_json(data):
    run("bondid.sensitivity", "--model", str(MODEL), "--data", "q0.csv", "q1.csv", "--free",
        *FREE, "--workers", "1", "--out", "sens", "--quiet", cwd=data)  # fmt: skip
    doc = check("sensitivity", data / "sens" / "sensitivity.json")
    assert doc["sweep"] is not None and len(doc["parameters"]) == len(FREE)


@pytest.mark.smoke
def test_diagnosis_json(data):
    run("bondid.diagnose", "--model", str(MODEL), "--data", "q0.csv", "q1.csv", "--effects",
        "sensor_delay", "--free", *FREE, "--points", "100", "--workers", "1", "--no-plots",
        "--out", "diag", "--quiet", cwd=data)  # fmt: skip
    doc = check("diagnosis", data / "diag" / "diagnosis.json")
    assert doc["verdict"]["effect"] in ("none", "sensor_delay")


@pytest.mark.smoke
def test_modes_json(tmp_path):
    run("bondid.modes", "--model", str(MODEL), "--fitted", str(MODEL), "--no-html", "--out",
        "modes", "--quiet", cwd=tmp_path)  # fmt: skip
    doc = check("modes", tmp_path / "modes" / "modes.json")
    f = [m["f_hz"] for m in doc["modes"]]
    assert f == sorted(f) and doc["fitted"]["modes"]


@pytest.mark.slow
def test_fleet_json(tmp_path):
    pytest.importorskip("dask.distributed")
    from bondid.fleet.synthetic import make_fleet
    from bondid.model import UrdfDocument

    make_fleet(
        UrdfDocument.load(MODEL), tmp_path / "machines", n_machines=5, parameters=FREE[:1],
        spread=0.05, freq=(1.0, 4000.0, 120), noise=0.02, seed=3,
    )  # fmt: skip
    run("bondid.fleet", "--model", str(MODEL), "--machines", "machines", "--out", "out",
        "--workers", "1", "--free", FREE[0], "--max-iter", "30", "--quiet",
        cwd=tmp_path)  # fmt: skip
    doc = check("fleet", tmp_path / "out" / "fleet.json")
    assert doc["counts"] == {"machines": 5, "ok": 5, "failed": 0}
    assert [p["name"] for p in doc["parameters"]] == FREE[:1]

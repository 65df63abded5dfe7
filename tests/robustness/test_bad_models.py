"""Physically impossible or broken models: every command exits 2 naming the file and the item
(issue 16, points 5 and 6); a CoM outside the geometry and a bad operating point warn."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from .conftest import fast_args, mutate, one_line_reason

TRANSMISSION = r'  <transmission name="x_trans">.*?</transmission>\n'

# case → (mutation of the bonder text, words the one-line reason must hold)
CASES: dict[str, tuple[object, tuple[str, ...]]] = {
    "negative_mass": ((r'<mass value="1.67"/>', '<mass value="-1.67"/>'), ("x_stage", "mass")),
    "zero_mass": ((r'<mass value="0.85"/>', '<mass value="0"/>'), ("y_stage", "mass")),
    "negative_inertia": ((r'ixx="0.00581"', 'ixx="-0.00581"'), ("x_stage", "negative")),
    "triangle": ((r'izz="0.015"', 'izz="0.05"'), ("x_stage", "triangle")),
    "negative_stiffness": (
        (r"<springStiffness>200000<", "<springStiffness>-200000<"),
        ("x_guide_ry", "stiffness"),
    ),
    "negative_damping": ((r'damping="1.6"', 'damping="-1.6"'), ("x_guide_ry", "damping")),
    "spring_on_fixed_joint": (
        (
            r"(<gazebo reference=\"x_guide_ty\">)",
            '<gazebo reference="x_guide_ry_offset"><springStiffness>5</springStiffness>'
            "</gazebo>\n  \\1",
        ),
        ("x_guide_ry_offset", "fixed"),
    ),
    "zero_axis": (
        (
            r'(<joint name="x_guide_ry" type="revolute">.*?)<axis xyz="0 1 0"/>',
            '\\1<axis xyz="0 0 0"/>',
        ),
        ("x_guide_ry", "axis"),
    ),
    "moving_body_without_inertia": (
        (r'(<link name="z_stage">\s*)<inertial>.*?</inertial>', "\\1"),
        ("'z'", "moves no mass"),
    ),
    "kinematic_loop": (
        (
            r"(<!-- ===== springs)",
            '<joint name="loop" type="fixed"><parent link="base"/><child link="x_stage"/>'
            "</joint>\n  \\1",
        ),
        ("kinematic loop", "x_stage"),
    ),
    "missing_mesh": (
        (
            r'(<collision name="x_stage[^"]*">\s*<origin[^>]*>\s*)<geometry>.*?</geometry>',
            '\\1<geometry><mesh filename="meshes/nope.stl"/></geometry>',
        ),
        ("x_stage", "nope.stl", "not found"),
    ),
    "duplicate_transmission": ((f"({TRANSMISSION})", "\\1\\1"), ("'x'", "two transmissions")),
    "no_transmission": (("ALL_TRANSMISSIONS", ""), ("no <transmission>",)),
    "binary_file": (("BINARY", ""), ("not a text file",)),
    "not_xml": (("TEXT", "this is not XML"), ("XML",)),
    "missing_file": (("MISSING", ""), ("cannot read",)),
}

COMMANDS = ("fit", "sensitivity", "diagnose", "modes", "simulate")


def _write_case(case: str, root: Path, bonder_text: str) -> Path:
    path = root / f"{case}.urdf"
    (pattern, repl), _ = CASES[case]  # type: ignore[misc]
    if pattern == "ALL_TRANSMISSIONS":
        path.write_text(mutate(bonder_text, TRANSMISSION.replace("x_trans", ".*?"), "", 3))
    elif pattern == "BINARY":
        path.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe\x00binary")
    elif pattern == "TEXT":
        path.write_text(repl)
    elif pattern != "MISSING":
        path.write_text(mutate(bonder_text, pattern, repl))
    return path


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("case", list(CASES))
def test_bad_model_exit_2_naming_file_and_item(command, case, inputs, run, tmp_path):
    model = _write_case(case, tmp_path, inputs["model"].read_text())
    out = tmp_path / ("o.csv" if command == "simulate" else "out")
    code, _, err = run(command, *fast_args(command, model, [inputs["d0"]], out))
    assert code == 2, err
    reason = one_line_reason(err)
    assert model.name in reason
    for word in CASES[case][1]:
        assert word in reason, reason
    assert not out.exists()  # checked before any work, nothing written


def test_com_outside_geometry_is_a_warning(inputs, run, tmp_path):
    text = mutate(
        inputs["model"].read_text(),
        r'(<link name="x_stage">\s*<inertial>\s*)<origin xyz="[^"]*"',
        '\\1<origin xyz="0.9 0 0"',
    )
    model = tmp_path / "com_out.urdf"
    model.write_text(text)
    code, out, _ = run("modes", "--model", model, "--no-html", "--out", tmp_path / "m")
    assert code == 0
    assert "warning:" in out and "x_stage" in out and "outside" in out
    saved = json.loads((tmp_path / "m" / "modes.json").read_text())["warnings"]
    assert any("x_stage" in w and "outside its collision geometry" in w for w in saved)


@pytest.mark.parametrize("command", ["modes", "simulate"])
def test_operating_point_outside_limits_warns(command, inputs, run, tmp_path):
    out = tmp_path / ("o.csv" if command == "simulate" else "m")
    argv = [*fast_args(command, inputs["model"], [], out), "--q", "x=0.5"]
    code, stdout, _ = run(command, *argv)
    assert code == 0
    assert "warning:" in stdout and "x = 0.5 is outside the joint's limits" in stdout


@pytest.mark.slow
def test_unstable_operating_point_warns_in_every_data_command(inputs, run, tmp_path):
    from bondid.model.document import UrdfDocument
    from bondid.model.parameters import set_parameter

    doc = UrdfDocument.load(inputs["model"])
    doc.set_stiffness("z", 0.0)
    set_parameter(doc, "z_stage.com.z", 0.01)  # the z stage balances above its pivot
    model = doc.write(tmp_path / "inverted.urdf")
    for command in ("fit", "sensitivity", "diagnose", "modes"):
        out = tmp_path / f"o_{command}"
        code, stdout, err = run(command, *fast_args(command, model, [inputs["d0"]], out))
        assert code in (0, 1), err  # a fit may not converge on such a model; no crash
        assert "unstable" in stdout, (command, stdout)
        main = {"fit": "fit.json", "sensitivity": "sensitivity.json",
                "diagnose": "diagnosis.json", "modes": "modes.json"}[command]  # fmt: skip
        saved = json.loads((out / main).read_text())["warnings"]
        assert any("unstable" in w for w in saved)


def test_diagnose_resolves_meshes_against_the_urdf_folder(inputs, run, tmp_path, monkeypatch):
    import trimesh

    folder = tmp_path / "machine"
    (folder / "meshes").mkdir(parents=True)
    trimesh.creation.box(extents=(0.1, 0.1, 0.05)).export(folder / "meshes" / "x.stl")
    text = mutate(
        inputs["model"].read_text(),
        r'(<collision name="x_stage[^"]*">\s*<origin[^>]*>\s*)<geometry>.*?</geometry>',
        '\\1<geometry><mesh filename="meshes/x.stl"/></geometry>',
    )
    model = folder / "m.urdf"
    model.write_text(text)
    elsewhere = tmp_path / "cwd"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    argv = fast_args("diagnose", model, [inputs["d0"]], tmp_path / "dg")
    argv[argv.index("--free") + 1] = "x_stage.com.x"  # needs the x_stage hull
    code, _, err = run("diagnose", *argv)
    assert code == 0, err


@pytest.mark.parametrize(("com_z", "warns_over_data"), [(0.01, True), (1e-9, False)])
def test_instability_too_slow_to_measure_is_not_reported_over_data(inputs, com_z, warns_over_data):
    """A free z pivot with its centre of mass ``com_z`` above it: 1 cm grows at 3.4 1/s (an
    unmeasurable machine), 1 nm at about 1e-5 1/s, which changes no line from 1 Hz on; both
    are reported when no data bound the band."""
    from bondid.model.document import UrdfDocument
    from bondid.model.parameters import set_parameter
    from bondid.validation.operating_point import UNSEEN_GROWTH, stability_warnings

    doc = UrdfDocument.load(inputs["model"])
    doc.set_stiffness("z", 0.0)
    set_parameter(doc, "z_stage.com.z", com_z)
    assert stability_warnings(doc, {}, "q"), "an unstable eigenvalue must be reported"
    over_data = stability_warnings(doc, {}, "q", f_min_hz=1.0)
    assert bool(over_data) is warns_over_data
    if over_data:
        growth = float(over_data[0].split("largest ")[1].split(" 1/s")[0])
        assert growth > UNSEEN_GROWTH * 2 * 3.141592653589793

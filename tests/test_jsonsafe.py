"""JSON-safe numbers (bondid.jsonsafe): what every JSON result is written through."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bondid.jsonsafe import json_safe, number


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        (1.5, 1.5),
        (3, 3.0),
        (np.float32(0.25), 0.25),
        (np.float64(-2.0), -2.0),
        (np.int64(7), 7.0),
        (float("nan"), None),
        (float("inf"), None),
        (-np.inf, None),
        (True, None),
        (np.bool_(True), None),
        (None, None),
        ("1.5", None),
        ([1.0], None),
    ],
)
def test_number_known_answers(value: object, expected: float | None) -> None:
    got = number(value)
    assert got == expected
    assert got is None or type(got) is float


def test_number_keeps_non_finite_when_asked() -> None:
    assert number(float("inf"), finite=False) == math.inf
    assert number(-np.inf, finite=False) == -math.inf
    nan = number(np.float64("nan"), finite=False)
    assert nan is not None and math.isnan(nan)
    assert number("x", finite=False) is None
    assert number(False, finite=False) is None


def test_json_safe_nested_structure_is_valid_json() -> None:
    value = {
        "a": np.array([[1.0, np.nan], [np.inf, 2.0]]),
        "b": (np.int32(3), np.bool_(False), "s", None, True),
        "c": [{"d": np.float64(-np.inf)}, np.array(4.5), np.array([], dtype=float)],
        "e": 7,
    }
    safe = json_safe(value)
    text = json.dumps(safe, allow_nan=False)  # raises on NaN/inf or NumPy types
    assert json.loads(text) == {
        "a": [[1.0, None], [None, 2.0]],
        "b": [3, False, "s", None, True],
        "c": [{"d": None}, 4.5, []],
        "e": 7,
    }
    assert type(safe["b"][0]) is int and type(safe["b"][1]) is bool


def test_json_safe_leaves_its_input_alone() -> None:
    arr = np.array([np.nan, 1.0])
    data = {"x": arr, "y": [np.nan]}
    json_safe(data)
    assert data["x"] is arr and np.isnan(arr[0]) and math.isnan(data["y"][0])


def test_json_safe_takes_any_mapping() -> None:
    from types import MappingProxyType

    safe = json_safe(MappingProxyType({"a": (np.nan, 1), "b": MappingProxyType({"c": np.inf})}))
    assert safe == {"a": [None, 1], "b": {"c": None}} and type(safe["b"]) is dict

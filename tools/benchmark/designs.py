"""The machine designs of the benchmark: a URDF each, written as a user would, and two
operating points (joint positions, SI) at which each is "measured"."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent / "designs"


@dataclass(frozen=True)
class Design:
    """One machine: its nominal URDF and the operating points of its measurements."""

    name: str
    path: Path
    operating_points: tuple[dict[str, float], ...]
    note: str


DESIGNS: dict[str, Design] = {
    d.name: d
    for d in (
        Design(
            "bonder",
            ROOT / "urdf" / "bonder.urdf",
            ({}, {"x": 0.05, "y": -0.03, "z": 0.1}),
            "reference wire bonder: x on y-stage, rocker about x (11 DOF)",
        ),
        Design(
            "bonder_b",
            HERE / "bonder_b.urdf",
            ({}, {"ya": -0.06, "xa": 0.04, "head": -0.12}),
            "second bonder: y carriage under an x slide, rocker about y (11 DOF)",
        ),
        Design(
            "gantry",
            HERE / "gantry_rotary.urdf",
            ({}, {"gy": 0.15, "gx": -0.2, "theta": 0.8}),
            "2-axis gantry (racking bridge) with a rotary head (10 DOF)",
        ),
        Design(
            "polar",
            HERE / "polar_handler.urdf",
            ({}, {"ext": 0.12, "lift": -0.03, "rot": 0.5}),
            "R-theta wafer handler: turntable, radial arm, lift at its tip (10 DOF)",
        ),
    )
}


def design(name: str) -> Design:
    """The design called ``name``; raises ``KeyError`` naming the valid ones."""
    try:
        return DESIGNS[name]
    except KeyError:
        raise KeyError(f"unknown design {name!r}; valid: {', '.join(DESIGNS)}") from None

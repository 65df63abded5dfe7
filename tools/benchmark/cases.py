"""The case list: designs × regimes × withheld effects, single and two-effect.

Per design, seven single-effect truths (two translational joint compliances at different
interfaces, a rotational one, a flexible base, soft mounts, a sensor delay, an actuator lag),
each in two regimes, plus two "none" truths (parameter errors only) in one regime each: 16
cases, 48 over the three designs (42 with an effect).
The regimes rotate with the effect and the design so that every regime sees every effect
class. Then 8 two-effect cases (structural + signal, two structural at different places).
"""

from __future__ import annotations

from dataclasses import dataclass

from .regimes import REGIMES
from .truth import TruthEffect as E


@dataclass(frozen=True)
class Case:
    name: str
    design: str
    regime: str
    effects: tuple[E, ...]
    seed: int

    @property
    def label(self) -> str:
        return " + ".join(e.effect for e in self.effects) or "none"

    @property
    def where(self) -> str:
        return " + ".join(e.location for e in self.effects) or "–"


def _jc(loc: str, f: float, offset=(0.02, -0.015)) -> E:
    return E("joint_compliance", loc, {"f": f, "offset": offset})


# per design: tag → effect; the order fixes the regime rotation
SINGLE: dict[str, dict[str, E]] = {
    "bonder": {
        "jct": _jc("x_stage->y_stage:tz", 900.0),
        "jcr": _jc("base->x_stage:rx", 450.0, (0.02, 0.015)),
        "fb": E("flexible_base", "base", {"f": 1200.0}),
        "sm": E("soft_mounts", "base", {"f": 20.0}),
        "sd": E("sensor_delay", "z", {"tau": 60e-6}),
        "al": E("actuator_lag", "y", {"T": 80e-6}),
        "jct2": _jc("base->x_stage:tz", 1300.0),
    },
    "bonder_b": {
        "jct": _jc("carriage_y->slide_x:tz", 700.0),
        "jcr": _jc("machine_bed->carriage_y:ry", 350.0, (0.025, 0.012)),
        "fb": E("flexible_base", "machine_bed", {"f": 1000.0}),
        "sm": E("soft_mounts", "machine_bed", {"f": 15.0}),
        "sd": E("sensor_delay", "all", {"tau": 25e-6}),
        "al": E("actuator_lag", "head", {"T": 120e-6}),
        "jct2": _jc("slide_x->rocker:tz", 1200.0),
    },
    "gantry": {
        "jct": _jc("bridge->carriage:tz", 600.0),
        "jcr": _jc("frame->bridge:ry", 250.0, (-0.06, 0.03)),
        "fb": E("flexible_base", "frame", {"f": 700.0}),
        "sm": E("soft_mounts", "frame", {"f": 12.0}),
        "sd": E("sensor_delay", "gx", {"tau": 40e-6}),
        "al": E("actuator_lag", "all", {"T": 50e-6}),
        "jct2": _jc("carriage->rotary_head:tx", 1400.0),
    },
    # stop 35: a fourth machine type, measured first in its own regime (mob: velocity)
    "polar": {
        "jct": _jc("pedestal->turntable:tz", 1100.0),
        "jcr": _jc("turntable->arm:rx", 420.0, (0.03, 0.015)),
        "fb": E("flexible_base", "pedestal", {"f": 900.0}),
        "sm": E("soft_mounts", "pedestal", {"f": 16.0}),
        "sd": E("sensor_delay", "ext", {"tau": 45e-6}),
        "al": E("actuator_lag", "lift", {"T": 90e-6}),
        "jct2": _jc("arm->fork:ty", 1300.0),
    },
}

DOUBLE: dict[str, dict[str, tuple[E, E]]] = {
    "bonder": {
        "jcr+al": (_jc("x_stage->y_stage:ry", 300.0, (0.015, 0.01)),
                   E("actuator_lag", "all", {"T": 40e-6})),
        "sm+sd": (E("soft_mounts", "base", {"f": 25.0}), E("sensor_delay", "x", {"tau": 40e-6})),
        "jct+jcr": (_jc("y_stage->z_stage:ty", 1500.0), _jc("base->x_stage:rx", 450.0)),
    },
    "bonder_b": {
        "jct+sd": (_jc("slide_x->rocker:tx", 1800.0), E("sensor_delay", "ya", {"tau": 50e-6})),
        "jcr+al": (_jc("carriage_y->slide_x:rz", 600.0, (0.02, 0.01)),
                   E("actuator_lag", "xa", {"T": 60e-6})),
        "fb+jct": (E("flexible_base", "machine_bed", {"f": 1500.0}),
                   _jc("carriage_y->slide_x:tz", 700.0)),
    },
    "gantry": {
        "jcr+sd": (_jc("bridge->carriage:rz", 450.0, (0.03, -0.02)),
                   E("sensor_delay", "all", {"tau": 30e-6})),
        "sm+al": (E("soft_mounts", "frame", {"f": 18.0}), E("actuator_lag", "gy", {"T": 100e-6})),
    },
    "polar": {
        "jcr+sd": (_jc("arm->fork:ry", 650.0, (0.02, -0.01)),
                   E("sensor_delay", "all", {"tau": 35e-6})),
        "jct+al": (_jc("arm->fork:ty", 1300.0), E("actuator_lag", "rot", {"T": 70e-6})),
    },
}  # fmt: skip

NONE_TAGS = ("none_a", "none_b")
#: designs measured in a regime of their own as well: the first regime of every single
#: effect, the first "none" case and the two-effect cases (the others rotate as for the rest)
OWN_REGIME = {"polar": "mob"}
#: the regimes the designs rotate through
ROTATION = REGIMES[:4]


def _regime(design: str, k: int, first: bool) -> str:
    """The regime of a case: the design's own for its first ones (:data:`OWN_REGIME`), else
    the ``k``-th of the rotation."""
    own = OWN_REGIME.get(design)
    return own if own and first else ROTATION[k % len(ROTATION)]


def all_cases() -> list[Case]:
    """Every case, in a fixed order (designs, then single, none and two-effect cases)."""
    out: list[Case] = []
    seed = 0
    for d, (design, singles) in enumerate(SINGLE.items()):
        for i, (tag, eff) in enumerate(singles.items()):
            for shift in (0, 2):
                seed += 1
                r = _regime(design, i + d + shift, shift == 0)
                out.append(Case(f"{design}/{tag}/{r}", design, r, (eff,), seed))
        for i, tag in enumerate(NONE_TAGS):
            seed += 1
            r = _regime(design, d + i, i == 0)
            out.append(Case(f"{design}/{tag}/{r}", design, r, (), seed))
        for i, (tag, pair) in enumerate(DOUBLE[design].items()):
            seed += 1
            r = _regime(design, d + i, True)
            out.append(Case(f"{design}/{tag}/{r}", design, r, pair, seed))
    return out


QUICK = ("gantry/jct/harsh", "bonder_b/none_a/nocoh", "bonder/al/acc")


# -- the open-world list: the later causes in the library, and causes outside it -------------

#: per tag, the (design, cause) pairs: each later cause of the library on two designs, and
#: two causes outside the library (:data:`.truth.OUTSIDE`)
OPEN: dict[str, tuple[tuple[str, E], ...]] = {
    "sdyn": (("bonder", E("sensor_dynamics", "y", {"f": 1100.0})),
             ("bonder_b", E("sensor_dynamics", "xa", {"f": 900.0}))),
    "mis": (("bonder", E("sensor_misalignment", "x,y", {"sensor": "x", "toward": "y",
                                                        "deg": 0.5, "deg_other": -0.2})),
            ("gantry", E("sensor_misalignment", "gx,gy", {"sensor": "gy", "toward": "gx",
                                                          "deg": 0.8, "deg_other": 0.3}))),
    "drv": (("bonder", E("drive_spring", "x", {"f": 5.0})),
            ("polar", E("drive_spring", "ext", {"f": 8.0}))),
    "flk": (("polar", E("flexible_link", "arm", {"f": 600.0})),
            ("bonder_b", E("flexible_link", "rocker", {"f": 1500.0}))),
    "gain": (("bonder", E("transducer_gain", "out.y", {"gain": 1.25})),
             ("bonder_b", E("transducer_gain", "in.xa", {"gain": 0.8}))),
    "hp": (("bonder", E("amplifier_highpass", "x", {"f": 3.0})),
           ("gantry", E("amplifier_highpass", "gy", {"f": 4.0}))),
    "xtalk": (("bonder_b", E("actuator_crosstalk", "xa,ya", {"share": 0.01})),
              ("polar", E("actuator_crosstalk", "ext,lift", {"share": 0.01}))),
    "appx": (("bonder", E("attached_mass", "x_stage", {"f": 200.0, "share": 0.25})),
             ("gantry", E("attached_mass", "carriage", {"f": 180.0, "share": 0.25}))),
}  # fmt: skip
#: the open list's seeds start here (apart from :func:`all_cases`'s)
OPEN_SEED = 500


def open_cases() -> list[Case]:
    """The open-world cases, in a fixed order: every (tag, design) of :data:`OPEN` in two
    regimes (the design's own first where it has one, :data:`OWN_REGIME`), rotating so that
    every regime sees the later causes and the causes outside the library. A case's class
    is its effect's :attr:`~.truth.TruthEffect.library` (None outside the library);
    :func:`leave_one_out` gives the ``--effects`` list without it."""
    out: list[Case] = []
    seed = OPEN_SEED
    for t, (tag, pairs) in enumerate(OPEN.items()):
        for d, (design, eff) in enumerate(pairs):
            for shift in (0, 2):
                seed += 1
                r = _regime(design, t + d + shift, shift == 0)
                out.append(Case(f"{design}/{tag}/{r}", design, r, (eff,), seed))
    return out


def classes(case: Case) -> tuple[str, ...]:
    """The library classes of ``case``'s causes (none for a cause outside the library)."""
    return tuple(dict.fromkeys(c for e in case.effects if (c := e.library) is not None))


def leave_one_out(case: Case, effects: tuple[str, ...] | None = None) -> tuple[str, ...]:
    """The ``--effects`` list of ``case``'s leave-one-class-out run: ``effects`` (default:
    every effect of the diagnosis's library) without the case's classes."""
    if effects is None:
        from bondid.diagnose.effects import available

        effects = tuple(available())
    drop = set(classes(case))
    return tuple(e for e in effects if e not in drop)

"""Truth machines: a nominal design with random parameter errors plus withheld effects.

Every effect here is built deliberately unlike the diagnosis's own candidate for it:

- ``joint_compliance``: a rotational DOF pivots off the bearing centre in *both* directions
  across its axis (the candidate's pivot options move one coordinate at a time), 2 % damping;
- ``flexible_base``: 5 unequal lumps, heavier at the bottom, x/y shear 1 : 1.3, compression
  3× (the candidate: 4 lumps of a uniform rod);
- ``soft_mounts``: six unequal mount stiffnesses whose axes pass through the bottom face of
  the base (the candidate's pass through its CoM);
- ``sensor_delay``: a pure delay ``e^{−jωτ}`` on one output or all;
- ``actuator_lag``: a current loop with two real poles, ``1/((1 + jωT)(1 + jωT/8))`` (the
  candidate: one pole).

The later causes (``sensor_dynamics``, ``sensor_misalignment``, ``drive_spring``,
``flexible_link``, ``transducer_gain``, ``actuator_crosstalk``) and two outside the
diagnosis's library (``amplifier_highpass``, ``attached_mass``) are built in
:mod:`.truth_structures` and :mod:`.truth_signals`; a truth's files come from
:func:`observe_data` (its read heads' deflections added to their outputs, its output and
input mixings and signal factors applied).

Each effect knows its class in the library (:attr:`TruthEffect.library`, None outside it:
what a leave-one-class-out run removes) and what a description of the remainder should
point at when no candidate explains it (:func:`expected_remainder`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bondid.model import UrdfDocument, insert_parasitic_joint, set_parameter
from bondid.model.parameters import get_parameter, link_inertial, parameter_infos, set_link_inertial

STRUCTURAL = ("joint_compliance", "flexible_base", "soft_mounts")
SIGNAL = ("sensor_delay", "actuator_lag")
EFFECTS = STRUCTURAL + SIGNAL
#: the later causes in the diagnosis's library, and the ones outside it
LIBRARY_MORE = ("sensor_dynamics", "sensor_misalignment", "drive_spring", "flexible_link",
                "transducer_gain", "actuator_crosstalk")  # fmt: skip
OUTSIDE = ("amplifier_highpass", "attached_mass")
ALL_EFFECTS = EFFECTS + LIBRARY_MORE + OUTSIDE


@dataclass(frozen=True)
class TruthEffect:
    """One withheld effect: its class, the location the diagnosis should name, and how it is
    built (``f`` Hz for structural ones, ``pivot_offset`` m for rotational compliances,
    ``tau`` / ``T`` s for the signal ones)."""

    effect: str
    location: str
    spec: dict[str, Any] = field(default_factory=dict)

    @property
    def library(self) -> str | None:
        """The diagnosis's effect class this cause belongs to (None: outside the library)."""
        return None if self.effect in OUTSIDE else self.effect


@dataclass(frozen=True)
class Remainder:
    """What a description of the remainder should point at for a cause no candidate
    explains, in the words of issue 57's list.

    Attributes:
        kind: ``missing_mode`` (a mode the model lacks, near ``band_hz``), ``output_row``
            (confined to the rows ``rows``: the sensor side), ``input_column`` (the columns
            ``columns``: the actuator side), ``low_frequency`` (a stiffness or mass line
            offset below ``band_hz[1]``), ``cross_talk`` (leakage into cross channels
            proportional to a direct one), ``delay`` (phase growing linearly with frequency).
        rows, columns: the output / input channels it lives in (empty: not confined).
        band_hz: ``(f_lo, f_hi)`` where it shows [Hz], or None (the whole band).
    """

    kind: str
    rows: tuple[str, ...] = ()
    columns: tuple[str, ...] = ()
    band_hz: tuple[float, float] | None = None


def perturb(doc: UrdfDocument, rng: np.random.Generator) -> UrdfDocument:
    """Random 10–30 % errors, random sign, on every mass, CoM coordinate, inertia tensor
    (scaled as a whole, so it stays physical) and non-zero spring and damper."""
    out = doc.copy()

    def fac() -> float:
        return 1.0 + float(rng.choice([-1.0, 1.0]) * rng.uniform(0.1, 0.3))

    for link in sorted({p.owner for p in parameter_infos(out) if p.is_inertial}):
        m, c, inertia = link_inertial(out, link)
        set_link_inertial(
            out, link, m * fac(), c * np.array([fac(), fac(), fac()]), inertia * fac()
        )
    for p in parameter_infos(out):
        if p.kind in ("stiffness", "damping") and get_parameter(out, p.name) > 0:
            set_parameter(out, p.name, get_parameter(out, p.name) * fac())
    return out


def effective_inertia(doc: UrdfDocument, joint: str) -> float:
    """``1/(M⁻¹)_jj`` of ``joint`` at the neutral configuration [kg or kg·m²]."""
    from bondid.linear.affine import build_affine_model

    am = build_affine_model(doc)
    j = am.dofs.index(joint)
    return float(1.0 / np.linalg.inv(am.mass_matrix())[j, j])


def truth_pivot(doc: UrdfDocument, location: str, offset: Sequence[float]) -> np.ndarray:
    """Pivot (child frame, m) of a truth rotational DOF: the interface's bearing centre moved
    by ``offset`` along both directions across the axis."""
    from bondid.diagnose.effects.topology import interfaces

    pair, axis = location.split(":")
    parent, child = pair.split("->")
    itf = next(i for i in interfaces(doc) if i.parent == parent and i.child == child)
    p = np.asarray(itf.pivot(doc), float).copy()
    across = [k for k in range(3) if k != "xyz".index(axis[1])]
    for k, d in zip(across, offset, strict=True):
        p[k] += d
    return p


def add_compliance(
    doc: UrdfDocument, location: str, f: float, offset=(0.02, -0.015)
) -> UrdfDocument:
    """A sprung DOF at ``"PARENT->CHILD:AXIS"`` whose spring alone, on the DOF's effective
    inertia, would resonate at ``f`` Hz (2 % damping)."""
    from bondid.diagnose.effects.topology import axis_vector, interfaces

    pair, axis = location.split(":")
    parent, child = pair.split("->")
    matches = [i for i in interfaces(doc) if i.parent == parent and i.child == child]
    if not matches or axis not in matches[0].missing:
        raise ValueError(f"{doc.source}: no interface {pair!r} missing axis {axis!r}")
    kind, vec = axis_vector(axis)
    piv = truth_pivot(doc, location, offset) if kind == "revolute" else np.zeros(3)
    out = doc.copy()
    name = f"truth_{child}_{axis}"
    insert_parasitic_joint(out, name, after=matches[0].last_joint, kind=kind, axis=vec,
                           pivot=piv, stiffness=1.0, damping=0.0)  # fmt: skip
    m = effective_inertia(out, name)
    k = m * (2 * np.pi * f) ** 2
    out.set_stiffness(name, k)
    out.set_damping(name, 2 * 0.02 * np.sqrt(k * m))
    return out


def add_flexible_base(doc: UrdfDocument, f: float) -> UrdfDocument:
    """The root as the top of a 5-lump free-free chain, masses M·(0.3, 0.25, 0.2, 0.15, 0.1)
    bottom to top, 4 cm segments, shear x : y = 1 : 1.3, compression 3×, ζ ≈ 2.5 %; the x
    shear stiffness puts the chain's first x mode at ``f``."""
    from bondid.diagnose.effects._chain import TRANSLATIONS, add_link, dof_chain
    from bondid.diagnose.effects.flexible_base import first_mode_w2

    out = doc.copy()
    root = out.root_link()
    M, c, inertia = link_inertial(out, root)
    masses = M * np.array([0.3, 0.25, 0.2, 0.15, 0.1])
    set_link_inertial(out, root, masses[-1], c, inertia)
    add_link(out, "tb_ground")
    nodes = [f"tb_{i}" for i in range(4)] + [root]
    for i in range(4):
        add_link(out, nodes[i], float(masses[i]))
    dof_chain(out, "tb_free", "tb_ground", nodes[0], TRANSLATIONS, xyz=(0, 0, -0.16),
              stiffness=[0.0] * 3)  # fmt: skip
    k = (2 * np.pi * f) ** 2 / first_mode_w2(masses)
    m_l = float(np.mean(masses))
    for i in range(4):
        ks = [k, 1.3 * k, 3.0 * k]
        ds = [2 * 0.025 * np.sqrt(kk * m_l) for kk in ks]
        dof_chain(out, f"tb_seg{i}", nodes[i], nodes[i + 1], TRANSLATIONS, xyz=(0, 0, 0.04),
                  stiffness=ks, damping=ds)  # fmt: skip
    return out


def _root_extent(doc: UrdfDocument) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) corners of the root link's collision hull (link frame, m)."""
    from bondid.diagnose.effects.topology import link_box

    box = link_box(doc, doc.root_link())
    if box is None:
        return np.array([-0.2, -0.2, 0.0]), np.array([0.2, 0.2, 0.1])
    return box


def add_soft_mounts(doc: UrdfDocument, f: float) -> UrdfDocument:
    """Four feet at the corners of the base's bottom face; the six mount springs (x, y, z,
    rx, ry, rz, all unequal: horizontal ≈ 0.6 f, vertical f) act about the centre of that
    face, 4 % damping."""
    from bondid.diagnose.effects._chain import ROTATIONS, TRANSLATIONS, add_link, dof_chain

    out = doc.copy()
    root = out.root_link()
    _, c, inertia = link_inertial(out, root)
    m = sum(float(lk.inertial.mass) for lk in out.robot.links if lk.inertial is not None)
    lo, hi = _root_extent(out)
    a, b = 0.45 * (hi[0] - lo[0]), 0.45 * (hi[1] - lo[1])  # feet at ±a (x), ±b (y)
    w = 2 * np.pi * f
    kv = m * w**2 / 4  # per foot
    kh = m * (0.6 * w) ** 2 / 4
    ks = [4 * kh, 4 * kh * 1.25, 4 * kv * 0.9, 4 * kv * b**2 * 1.15, 4 * kv * a**2 * 0.8,
          4 * kh * (a**2 + b**2)]  # fmt: skip
    inert = [m, m, m, inertia[0, 0] + m * c[2] ** 2, inertia[1, 1] + m * c[2] ** 2, inertia[2, 2]]
    ds = [2 * 0.04 * np.sqrt(k * mi) for k, mi in zip(ks, inert, strict=True)]
    at = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    add_link(out, "tm_ground")
    dof_chain(out, "tm", "tm_ground", root, TRANSLATIONS + ROTATIONS, xyz=at, back=-at,
              stiffness=ks, damping=ds)  # fmt: skip
    return out


def hinge_modes(truth: UrdfDocument, link: str) -> list[float]:
    """The frequencies [Hz] of the truth machine's modes (neutral pose) whose most energetic
    DOF is one of ``link``'s bending hinges (:mod:`.truth_structures`), lowest first.
    ``spec["f"]`` sets the first mode of what the link carries with its root clamped; in the
    assembled machine the modes the hinges drive lie elsewhere (up to several times higher
    on the benchmark's designs), and a missing mode of the remainder there is the bending
    link's."""
    from bondid.linear import build_affine_model
    from bondid.modes.analysis import modal_analysis

    modes = modal_analysis(build_affine_model(truth).linear_model()).vibration_modes()
    return [m.f_hz for m in modes if m.dominant_dof.startswith(f"{link}_truth_hinge")]


def expected_remainder(e: TruthEffect, truth: UrdfDocument | None = None) -> tuple[Remainder, ...]:
    """What a right description of ``e``'s remainder points at (the most telling first; one
    of them is enough); ``truth``: the truth model, for a bending link (:func:`hinge_modes`:
    one band around each mode its hinges drive)."""
    spec, loc = e.spec, e.location
    if e.effect == "flexible_link" and truth is not None:
        bending = hinge_modes(truth, loc)
        if bending:
            return tuple(Remainder("missing_mode", band_hz=(0.7 * f, 1.4 * f)) for f in bending)
    if e.effect == "sensor_dynamics":
        band = (0.7 * spec["f"], 1.4 * spec["f"])
        return (Remainder("output_row", rows=(loc,), band_hz=band),
                Remainder("missing_mode", rows=(loc,), band_hz=band))  # fmt: skip
    if e.effect == "sensor_misalignment":
        return (Remainder("cross_talk", rows=(spec["sensor"],)),
                Remainder("output_row", rows=(spec["sensor"],)))  # fmt: skip
    if e.effect == "transducer_gain":
        side, chan = loc.split(".", 1)
        return (Remainder("output_row", rows=(chan,)) if side == "out"
                else Remainder("input_column", columns=(chan,)),)  # fmt: skip
    if e.effect == "drive_spring":
        return (Remainder("low_frequency", rows=(loc,), columns=(loc,),
                          band_hz=(0.0, 3.0 * spec["f"])),)  # fmt: skip
    if e.effect == "amplifier_highpass":
        return (
            Remainder("input_column", columns=(loc,), band_hz=(0.0, 3.0 * spec["f"])),
            Remainder("low_frequency", columns=(loc,), band_hz=(0.0, 3.0 * spec["f"])),
        )
    if e.effect == "actuator_crosstalk":
        a = loc.split(",")[0]
        return (Remainder("cross_talk", columns=(a,)), Remainder("input_column", columns=(a,)))
    if e.effect == "sensor_delay":
        return (Remainder("delay", rows=() if loc == "all" else (loc,)),)
    if e.effect == "actuator_lag":
        return (Remainder("input_column", columns=() if loc == "all" else (loc,)),)
    f = float(spec.get("f", 0.0))
    return (Remainder("missing_mode", band_hz=(0.7 * f, 1.4 * f) if f else None),)


def strengthen(e: TruthEffect) -> TruthEffect:
    """One strengthening step of a later cause (:mod:`.visibility`): a mode that shows
    more (a lower bracket or bending mode; a stiffer carrier; a heavier appendage), a larger
    angle, gain error, share or corner."""
    spec = dict(e.spec)
    if e.effect in ("sensor_dynamics", "flexible_link"):
        spec["f"] *= 0.75
    elif e.effect in ("drive_spring", "amplifier_highpass"):
        spec["f"] *= 1.5
    elif e.effect == "sensor_misalignment":
        spec["deg"] *= 1.5
        spec["deg_other"] = spec.get("deg_other", 0.0) * 1.5
    elif e.effect == "transducer_gain":
        spec["gain"] = float(np.exp(1.5 * np.log(spec["gain"])))
    elif e.effect in ("actuator_crosstalk", "attached_mass"):
        spec["share"] *= 1.5
    else:
        raise ValueError(f"no strengthening rule here for {e.effect!r}")
    return TruthEffect(e.effect, e.location, spec)


def signal_factor(
    effects: Sequence[TruthEffect], f_hz: np.ndarray, outputs: Sequence[str], inputs: Sequence[str]
) -> np.ndarray:
    """``(n_out, n_in, n_freq)`` factor of the signal effects: sensor delays on rows, actuator
    lags and amplifier high-passes on columns (1 elsewhere; the other causes are built into
    the truth model or mix channels, :func:`observe_data`)."""
    G = np.ones((len(outputs), len(inputs), np.size(f_hz)), complex)
    w = 2 * np.pi * np.asarray(f_hz, float)
    for e in effects:
        if e.effect == "sensor_delay":
            rows = [i for i, o in enumerate(outputs) if e.location in ("all", o)]
            G[rows] *= np.exp(-1j * w * e.spec["tau"])
        elif e.effect == "actuator_lag":
            cols = [i for i, o in enumerate(inputs) if e.location in ("all", o)]
            T = e.spec["T"]
            G[:, cols] *= 1.0 / ((1.0 + 1j * w * T) * (1.0 + 1j * w * T / 8.0))
        elif e.effect == "amplifier_highpass":
            from .truth_signals import highpass

            cols = [i for i, o in enumerate(inputs) if e.location == o]
            G[:, cols] *= highpass(w, e.spec["f"], e.spec.get("zeta", 0.7))
    return G


def observe_data(
    truth: UrdfDocument, effects: Sequence[TruthEffect], op: dict[str, float], f: np.ndarray,
    quantity: str = "receptance", outputs: Sequence[str] | None = None,
):  # fmt: skip
    """The exact :class:`~bondid.data.measurement.FrfData` of ``truth`` at ``op`` as the files
    hold it (:func:`.truth_signals.observe` with :func:`signal_factor`)."""
    from .truth_signals import observe

    def factor(ff, outs, ins):
        return signal_factor(effects, ff, outs, ins)

    return observe(truth, effects, op, f, quantity, outputs, factor)


def observed_like(truth: UrdfDocument, effects: Sequence[TruthEffect], ds) -> np.ndarray:
    """The exact FRF of ``truth`` in the layout of the data set ``ds`` (its operating point,
    frequencies, quantity, outputs; its inputs' columns) ``(n_out, n_in, n_freq)``."""
    d = observe_data(truth, effects, dict(ds.operating_point), ds.freq_hz, ds.quantity, ds.outputs)
    return d.H[:, [d.inputs.index(i) for i in ds.inputs], :]


def truth_model(nominal: UrdfDocument, effects: Sequence[TruthEffect], seed: int) -> UrdfDocument:
    """The nominal design with random parameter errors (seeded) and the structural effects."""
    doc = perturb(nominal, np.random.default_rng(1000 + seed))
    for e in effects:
        if e.effect == "joint_compliance":
            doc = add_compliance(doc, e.location, e.spec["f"], e.spec.get("offset", (0.02, -0.015)))
        elif e.effect == "flexible_base":
            doc = add_flexible_base(doc, e.spec["f"])
        elif e.effect == "soft_mounts":
            doc = add_soft_mounts(doc, e.spec["f"])
        elif e.effect in ALL_EFFECTS[len(EFFECTS) :]:
            doc = _later_cause(doc, e)
        elif e.effect not in SIGNAL:
            raise ValueError(f"unknown effect {e.effect!r}; valid: {', '.join(ALL_EFFECTS)}")
    return doc


def _later_cause(doc: UrdfDocument, e: TruthEffect) -> UrdfDocument:
    """``doc`` with a later cause built in (the signal-only ones leave it as it is)."""
    from . import truth_signals as sig
    from . import truth_structures as st

    s = e.spec
    if e.effect == "sensor_dynamics":
        return sig.add_sensor_head(doc, e.location, s["f"], s.get("zeta", 0.03))
    if e.effect == "transducer_gain":
        out = doc.copy()
        out.set_gain(f"gain.{e.location}", s["gain"])
        return out
    if e.effect == "drive_spring":
        return st.add_cable_carrier(doc, e.location, s["f"])
    if e.effect == "flexible_link":
        return st.add_bending_arm(doc, e.location, s["f"])
    if e.effect == "attached_mass":
        return st.add_attached_mass(doc, e.location, s["f"], s["share"])
    return doc

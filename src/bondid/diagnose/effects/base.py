"""The plugin interface of the candidate effects: :class:`Effect`, :class:`Candidate`.

An *effect* is a kind of physics the nominal model may miss (``joint_compliance``,
``flexible_base``, ...). For a given model it proposes one :class:`Candidate` per location.
A candidate says how it augments the model and which new parameters it brings:

* a *structural* candidate edits a copy of the URDF (:meth:`Effect.augment`): new joints,
  links, springs, dampers. Each new parameter then sets one or several named URDF parameters
  linearly (``members``: ``URDF value = factor · parameter``), so tied parameters (one shear
  stiffness for every segment of a lumped chain, one vertical stiffness per foot) stay one
  number and the augmented model stays an ordinary URDF that can be written and inspected;
* a *modifier* candidate leaves the URDF alone and multiplies the model FRF by a factor
  ``G(ω; θ)`` per channel (``sensor_delay``, ``actuator_lag``): :meth:`Effect.modifier`
  returns ``G`` ``(n_out, n_in, n_f)`` and its exact derivatives ``(n_out, n_in, n_f, n_θ)``;
  a modifier may also mix the outputs or the inputs (``H ← L H R``, e.g. a sensor
  misalignment): an effect with ``mixes = True`` returns the matrices and their derivatives
  from :meth:`Effect.mixing` (:class:`bondid.cost.modifier.Mixing`; the factor ``G`` acts
  after the mixing).

Every new parameter is positive and refitted on a log scale within its bounds, except a
*signed* parameter (``NewParameter.signed``: a mixing entry, a log-gain, a pivot's shift,
near 0 and of either sign), refitted on a linear scale in steps of its ``typical`` size.
``scan`` is the exponent with which it follows a common scale factor in the coarse 1-D scan
that picks the refit's starting point (0 = not scanned; 1 = proportional; 0.5 = with the
square root, e.g. a damping that keeps the damping ratio while a stiffness is scanned).

Adding an effect is one file: subclass :class:`Effect`, set ``name`` and ``description``,
implement :meth:`~Effect.candidates` (and :meth:`~Effect.augment` or :meth:`~Effect.modifier`),
and decorate the class with :func:`bondid.diagnose.effects.register`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...cost.modifier import Mixing
from ...model.document import UrdfDocument


@dataclass(frozen=True)
class NewParameter:
    """One parameter a candidate adds.

    Attributes:
        name: readable name, e.g. ``stiffness`` or ``tau_s`` (unique in the candidate).
        initial: starting value (SI), > 0 (any sign when ``signed``).
        lower, upper: bounds (SI), ``0 < lower ≤ initial ≤ upper`` (``lower ≤ initial ≤
            upper`` when ``signed``).
        unit: SI unit text.
        members: ``((URDF parameter name, factor), ...)``: the URDF values it sets
            (structural candidates); empty for modifier parameters.
        scan: exponent in the starting-point scan (see the module docstring).
        strength: the parameter sets how far the effect is from absent (a stiffness, whose
            compliance vanishes as it grows; a delay or a lag time). The verdict asks the data
            to determine at least one of a candidate's strength parameters
            (:func:`bondid.diagnose.scoring.strength_z`). For a signed parameter the Wald
            test ``|value|/std`` is that of its absence (0).
        signed: refitted on a linear scale, of either sign (absent at 0): a modifier's
            parameter, or a structural one whose member is a model-level parameter of either
            sign (a mimic multiplier: a pivot's shift).
        typical: the typical size of a signed parameter, the unit of its refit's variable.
    """

    name: str
    initial: float
    lower: float
    upper: float
    unit: str
    members: tuple[tuple[str, float], ...] = ()
    scan: float = 0.0
    strength: bool = False
    signed: bool = False
    typical: float = 1.0


@dataclass(frozen=True)
class Candidate:
    """One effect at one location.

    Attributes:
        effect: the effect's name (spec table: ``joint_compliance`` ...).
        location: where (``"x_stage->y_stage:tz"``, ``"base"``, ``"x"``, ``"all"``) or None.
        parameters: the new parameters (see :class:`NewParameter`).
        spec: effect-specific data needed by :meth:`Effect.augment` / :meth:`Effect.modifier`
            (plain values only, so a candidate pickles to a worker process).
        scan_grid: factors of the starting-point scan (empty = no scan).
        description: one line for humans.
        ref_hz: for a structural candidate, the frequency [Hz] of its (first) new mode at the
            initial values; scaling the ``scan = 1`` parameters by ``(f/ref_hz)²`` moves it
            to ``f``, which is how identified missing modes seed the scan. None = no such
            mode (FRF modifiers).
        variants: alternatives of this candidate at the same location that differ in a detail
            the refit does not vary continuously (e.g. the pivot of a rotational DOF, which
            enters the kinematics); the screening gives each a start of its own, and the
            candidate's refit tries them in the order of their figures.
    """

    effect: str
    location: str | None
    parameters: tuple[NewParameter, ...]
    spec: dict[str, Any] = field(default_factory=dict)
    scan_grid: tuple[float, ...] = ()
    description: str = ""
    ref_hz: float | None = None
    variants: tuple[Candidate, ...] = ()

    @property
    def label(self) -> str:
        return f"{self.effect}@{self.location}" if self.location else self.effect


class Effect:
    """Base class of an effect plugin (see the module docstring)."""

    #: spec name of the effect
    name: str = ""
    #: one line for ``--help``
    description: str = ""
    #: True when the effect multiplies the FRF instead of editing the URDF
    is_modifier: bool = False
    #: True when the (modifier) effect mixes outputs or inputs (:meth:`mixing`)
    mixes: bool = False

    def candidates(self, doc: UrdfDocument) -> list[Candidate]:
        """One candidate per location where this effect could act on ``doc``."""
        raise NotImplementedError

    def augment(self, doc: UrdfDocument, candidate: Candidate) -> UrdfDocument:
        """A copy of ``doc`` with the effect built in at the candidate's initial values."""
        return doc.copy()

    def detail(self, doc: UrdfDocument, candidate: Candidate) -> str:
        """What the refitted model ``doc`` with ``candidate`` built in says about it beyond
        its parameters, in words (e.g. where a rotation pivots); "" when nothing."""
        return ""

    def modifier(
        self,
        candidate: Candidate,
        values: np.ndarray,
        freq_hz: np.ndarray,
        outputs: tuple[str, ...],
        inputs: tuple[str, ...],
    ) -> tuple[np.ndarray, np.ndarray]:
        """FRF factor ``G`` ``(n_out, n_in, n_f)`` and ``dG/dθ`` ``(n_out, n_in, n_f, n_θ)``.

        ``values`` ``(n_θ,)`` are the candidate's parameters in order, SI units.
        """
        n = len(candidate.parameters)
        shape = (len(outputs), len(inputs), np.size(freq_hz))
        return np.ones(shape, complex), np.zeros((*shape, n), complex)

    def mixing(
        self,
        candidate: Candidate,
        values: np.ndarray,
        outputs: tuple[str, ...],
        inputs: tuple[str, ...],
    ) -> Mixing | None:
        """The output/input mixing ``L``, ``R`` at ``values`` (``(n_θ,)``, SI) and their
        derivatives (:class:`bondid.cost.modifier.Mixing`), or None (no mixing: the default)."""
        return None


def spring_parameters(
    joint: str, k0: float, d0: float, k_span: tuple[float, float], rotational: bool
) -> tuple[NewParameter, NewParameter]:
    """The stiffness (the strength, scanned) and damping of a new or freed spring at
    ``joint``: starts ``k0``, ``d0`` (SI); the stiffness within ``k_span`` × ``k0`` (e.g. a
    mode moved from 3 Hz to 40 kHz), the damping within 10⁻³…10³ × ``d0``, scanned with the
    square root of the stiffness so the damping ratio stays."""
    u_k, u_d = ("N*m/rad", "N*m*s/rad") if rotational else ("N/m", "N*s/m")
    return (
        NewParameter("stiffness", k0, k0 * k_span[0], k0 * k_span[1], u_k,
                     ((f"{joint}.stiffness", 1.0),), scan=1.0, strength=True),
        NewParameter("damping", d0, d0 * 1e-3, d0 * 1e3, u_d, ((f"{joint}.damping", 1.0),),
                     scan=0.5),
    )  # fmt: skip


def per_joint_candidates(
    effect: Effect,
    doc: UrdfDocument,
    parameters: NewParameter | tuple[NewParameter, ...],
    grid: tuple[float, ...],
    what: str,
) -> list[Candidate]:
    """One candidate per driven joint (location = the joint) and one for all of them together
    (location ``"all"``), each with the new ``parameters`` (one or a tuple) and the scan
    ``grid``; ``what`` completes the description (``"delay on output(s)"``)."""
    params = parameters if isinstance(parameters, tuple) else (parameters,)
    joints = [t.joint for t in doc.transmissions]
    return [
        Candidate(effect.name, loc, params, {}, grid, f"{what} {loc}") for loc in [*joints, "all"]
    ]

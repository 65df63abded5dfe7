"""``<mimic>`` joints as coupled DOFs: ``q_j = a·q_master + b``.

The linearisation is computed with every joint free (Pinocchio's default reading of a URDF),
then reduced with the constant map ``δq_full = T δq_red`` (``T`` has a 1 for every free
coordinate and ``a`` in the master's column for a mimic joint): ``M_red = Tᵀ M T``, the
gravity stiffness ``Tᵀ (∂g/∂q) T`` (exact: ``T`` is constant), ``B_red = Tᵀ B``,
``C_red = C T``. Every parameter stays linear (``M_basis`` and ``G_basis`` are reduced the
same way). A mimic joint's own spring and damper act on ``a·δq_master``: they are folded,
fixed, into the master's (``a²·k``) and are not fitted parameters.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..exceptions import ModelError, OperatingPointError
from ..model.document import UrdfDocument


@dataclass(frozen=True)
class Coupling:
    master: str
    multiplier: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class Coupled:
    """A model with mimic joints in every joint's coordinates (kept on its reduced
    :class:`~.affine.AffineModel` so that a multiplier can be varied,
    :mod:`bondid.linear.coupling`).

    Attributes:
        full: its linearisation with every joint free (an :class:`~.affine.AffineModel`;
            kinematic ``B``, ``C``, no gains).
        couplings: mimic joint → its :class:`Coupling` (master, multiplier, offset).
    """

    full: Any
    couplings: dict[str, Coupling]


def mimic_couplings(doc: UrdfDocument, where: str) -> dict[str, Coupling]:
    """Movable mimic joint → its coupling; refuses chains and non-movable masters."""
    movable = set(doc.movable_joint_names)
    out: dict[str, Coupling] = {}
    for j in doc.robot.joints:
        m = getattr(j, "mimic", None)
        if m is None or j.name not in movable:
            continue
        a = 1.0 if m.multiplier is None else float(m.multiplier)
        b = 0.0 if m.offset is None else float(m.offset)
        out[j.name] = Coupling(str(m.joint), a, b)
    for name, c in out.items():
        if c.master not in movable or c.master in out:
            raise ModelError(
                f"{where}: joint {name!r} mimics {c.master!r}, which is not a movable joint"
                " without <mimic> of its own; a mimic must follow an independent joint"
            )
    return out


def full_operating_point(
    op: Mapping[str, float], couplings: Mapping[str, Coupling], where: str
) -> dict[str, float]:
    """The operating point with every mimic joint placed from its master (``a·q + b``)."""
    full = dict(op)
    for name, c in couplings.items():
        if name in op:
            raise OperatingPointError(
                f"{where}: operating point names {name!r}, a mimic of {c.master!r}; give"
                f" {c.master!r} instead"
            )
        full[name] = c.multiplier * float(op.get(c.master, 0.0)) + c.offset
    return full


def reduction(
    dofs: tuple[str, ...], couplings: Mapping[str, Coupling]
) -> tuple[np.ndarray, tuple[str, ...]]:
    """``T`` ``(nv_full, nv_red)`` and the reduced coordinate names."""
    red = tuple(d for d in dofs if d not in couplings)
    T = np.zeros((len(dofs), len(red)))
    for i, d in enumerate(dofs):
        c = couplings.get(d)
        if c is None:
            T[i, red.index(d)] = 1.0
        else:
            T[i, red.index(c.master)] = c.multiplier
    return T, red


def reduce_matrices(
    T: np.ndarray, mats: Mapping[str, np.ndarray]
) -> dict[str, np.ndarray]:  # fmt: skip
    """``Tᵀ X T`` over the last two axes of every array in ``mats``.

    Two broadcast matrix products: this runs at every cost evaluation of a model with a
    coupled joint (a free pivot), on the parameter bases too, where a three-operand
    contraction costs about a hundred times as much."""
    return {k: T.T @ v @ T for k, v in mats.items()}

"""The defaults of ``python -m bondid.fit`` that decide what a plain run does, in one place.

* :data:`DEFAULT_FREE`: the free parameters when none are named: ``default``
  (:func:`default_free`: every inertial parameter and every non-zero stiffness and damping).
* :data:`DEFAULT_WIDTH`: the relative width τ of the prior toward the model's values
  (:mod:`bondid.optim.prior`): the model's values are taken as right to about ±25 % (1σ), so
  the default bounds (±50 %) sit at 2σ.
"""

from __future__ import annotations

import argparse
import math

from ..exceptions import ConfigError
from ..model.document import UrdfDocument

DEFAULT_FREE: tuple[str, ...] = ("default",)
DEFAULT_WIDTH = 0.25


def check_prior(value: object, where: str) -> float:
    """A prior width: a finite number ≥ 0 (0 = no prior)."""
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if ok and math.isfinite(float(value)) and float(value) >= 0:  # type: ignore[arg-type]
        return float(value)  # type: ignore[arg-type]
    raise ConfigError(
        f"{where}: {value!r} is not a prior width; valid: a relative width >= 0"
        f" (default {DEFAULT_WIDTH}; 0 = no prior)"
    )


def _width(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan  # refused with the message of check_prior


def add_prior_arg(p: argparse._ActionsContainer) -> None:
    p.add_argument(
        "--prior", type=_width, metavar="WIDTH",
        help="relative width of a weak prior toward the model's values, scaled by the data's"
        f" noise: what the data cannot determine stays near the model (default {DEFAULT_WIDTH};"
        " 0 = none)",
    )  # fmt: skip


def default_free(doc: UrdfDocument) -> list[str]:
    """The names of ``--free default`` (the parameter group ``default``, see
    :mod:`bondid.model.parameters`), model order."""
    from ..model.parameters import group_members

    return group_members(doc, "default")

"""Parameter ties declared in a model: parameters of one kind that share one value.

A *tie* is a group of parameters of one kind (a joint's ``stiffness`` or ``damping``, a link's
``mass``, CoM component or inertia component) that take one value: one damping for every joint
of a lightly damped structure, one stiffness, one mass and one pitch inertia for each set of
identical segments. It is declared with ``--tie PATTERN`` or a study's ``[ties]`` table
(names and globs, :func:`bondid.model.tie_declaration.declare_tie`) and kept in the model as a URDF
extension element that other URDF readers ignore, so every command and every copy of the
model (``fitted.urdf`` too) sees it::

    <parameter_tie name="damping" members="j1.damping j2.damping j3.damping"/>

In a fit, the first member that is free (model order) is fitted and the others follow it
(:func:`leader_ties`; :class:`bondid.optim.tied.TiedParameters` carries the exact
derivatives): a tie is free as soon as one of its members is free.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from ..exceptions import ModelError

TIE_TAG = "parameter_tie"
#: the parameter kinds a tie may hold (all members of a tie are of one kind)
TIEABLE = ("stiffness", "damping", "mass", "com", "inertia")


@dataclass(frozen=True)
class Tie:
    """A tie: its name (for messages) and its members, model order, at least two."""

    name: str
    members: tuple[str, ...]

    def to_element(self) -> ET.Element:
        return ET.Element(TIE_TAG, {"name": self.name, "members": " ".join(self.members)})


def tie_from_element(el: ET.Element, where: str) -> Tie:
    """A ``<parameter_tie>`` element → :class:`Tie` (raises :class:`ModelError`)."""
    name = el.get("name", "")
    members = tuple(el.get("members", "").split())
    if len(members) < 2 or len(set(members)) != len(members):
        raise ModelError(
            f"{where}: <{TIE_TAG} name={name!r}>: members {' '.join(members)!r}; give two or"
            " more distinct parameter names"
        )
    return Tie(name, members)


def model_ties(doc: Any) -> list[Tie]:
    """The ties declared in a :class:`~bondid.model.document.UrdfDocument`, file order."""
    where = doc.source or "<URDF>"
    return [tie_from_element(el, where) for el in doc.extras if el.tag == TIE_TAG]


def set_tie(doc: Any, tie: Tie) -> None:
    """Add a tie to the model, or replace the one of the same name."""
    doc.extras = [el for el in doc.extras if not (el.tag == TIE_TAG and el.get("name") == tie.name)]
    doc.extras.append(tie.to_element())


def followers(ties: Iterable[Tie], chosen: Iterable[str]) -> set[str]:
    """The members of ``ties`` that follow another chosen member (every chosen member of a
    tie but its first one, in the order of ``chosen``)."""
    chosen = list(chosen)
    out: set[str] = set()
    for tie in ties:
        free = [n for n in chosen if n in tie.members]
        out.update(free[1:])
    return out


def leader_ties(ties: Iterable[Tie], names: Sequence[str]) -> dict[str, list[tuple[str, float]]]:
    """The ties of a fit over the free ``names``, as :class:`bondid.optim.problem.FitProblem`
    takes them: ``{leader: [(member, 1.0), ...]}`` for every tie with a member among
    ``names`` (its leader: that member).

    Raises:
        ModelError: two members of one tie are both among ``names`` (each would be fitted on
            its own; :func:`bondid.model.parameters.select_parameters` keeps only the first).
    """
    out: dict[str, list[tuple[str, float]]] = {}
    for tie in ties:
        free = [n for n in names if n in tie.members]
        if not free:
            continue
        if len(free) > 1:
            raise ModelError(
                f"tie {tie.name!r}: {', '.join(free)} are all free; a tie is fitted as one"
                f" value: free only {free[0]}"
            )
        out[free[0]] = [(m, 1.0) for m in tie.members if m != free[0]]
    return out

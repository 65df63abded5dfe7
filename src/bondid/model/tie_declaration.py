"""Declaring a tie in a model: the parameters a pattern names take one value
(:mod:`.ties` keeps it in the model; a fit follows it)."""

from __future__ import annotations

import fnmatch
from collections.abc import Iterable

from ..exceptions import ParameterError
from .document import UrdfDocument
from .parameters import get_parameter, parameter_infos, set_parameter
from .ties import TIEABLE, Tie, model_ties, set_tie


def declare_tie(doc: UrdfDocument, name: str, items: Iterable[str], where: str) -> Tie:
    """Tie the parameters that ``items`` (names and globs, comma- or space-separated)
    match into one value, in ``doc`` (:mod:`.ties`); every member is set to the first one's
    value (model order).

    Raises:
        ParameterError: a pattern matches nothing, fewer than two parameters, a parameter
            of a kind that cannot be tied (a gain, a mix, ...), members of two kinds, or a member
            already in another tie (the message names ``where``).
    """
    infos = {p.name: p for p in parameter_infos(doc)}
    hits: set[str] = set()
    for item in items:
        for token in item.replace(",", " ").split():
            found = [n for n in infos if fnmatch.fnmatchcase(n, token)]
            if not found:
                raise ParameterError(
                    f"{where}: tie {name!r}: {token!r} matches no parameter of"
                    f" {doc.source or '<URDF>'}; give parameter names or globs of one kind"
                    " (*.damping, seg*.stiffness, seg*.mass, seg*.inertia.iyy)"
                )
            hits.update(found)
    members = [n for n in infos if n in hits]
    kinds = {infos[n].kind for n in members}
    # a CoM or inertia tie holds one component: x of one body equal to y of another is not
    # what identical parts share
    keys = {infos[n].component_key for n in members}
    if len(members) < 2 or not kinds <= set(TIEABLE) or len(keys) != 1:
        raise ParameterError(
            f"{where}: tie {name!r} holds {', '.join(members)}; valid: two or more"
            f" parameters of one kind ({', '.join(TIEABLE)}), and of one component for a"
            " CoM or inertia tie (seg*.inertia.iyy)"
        )
    for other in model_ties(doc):
        shared = set(other.members) & set(members)
        if other.name != name and shared:
            raise ParameterError(
                f"{where}: tie {name!r}: {', '.join(sorted(shared))} already in tie"
                f" {other.name!r}; a parameter can be in one tie only"
            )
    value = get_parameter(doc, members[0])
    for m in members[1:]:
        set_parameter(doc, m, value)
    tie = Tie(name, tuple(members))
    set_tie(doc, tie)
    return tie

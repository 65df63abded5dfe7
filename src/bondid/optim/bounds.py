"""Default bounds of the fitted parameters, and the link hulls they (and the fit) refer to.

Relative bounds are ``value · (1 ± rel)`` around the model's value, with these refinements:

* ``mass``: ``m (1 ± rel)``, lower bound at least 0.
* ``com``: ``c ± rel · max(|c|, 0.1 ℓ)`` with ``ℓ`` the diagonal (m) of the link hull's bounding
  box — a CoM near the link origin still gets room proportional to the body's size (without
  geometry ``ℓ`` is taken as 0.1 m).
* ``inertia``: the diagonal entries ``I (1 ± rel)`` (``I ± rel · max(|I|, 0.1 Ī)``, ``Ī`` the
  link's mean principal moment); a product of inertia ``I_ab ± rel · √(Σ_aa Σ_bb)`` with
  ``Σ = ½ tr(I) 𝟙 − I`` the link's second moment about its CoM: ``√(Σ_aa Σ_bb)`` is the largest
  magnitude the product can have for a physically consistent body, so a product near 0 gets
  room in proportion to the body's extent in both directions (a thin body little across it).
* ``stiffness`` / ``damping``: ``v (1 ± rel)`` and never below 0. A value of 0 has nothing to
  be relative to; its bounds are ``[0, K_MAX]`` and ``[0, D_MAX]`` with
  ``K_MAX = STIFF_FACTOR · M_jj · (2π f_max)²`` and ``D_MAX = DAMP_FACTOR · M_jj · 2π f_max``:
  ``M_jj`` is the joint's effective inertia (the diagonal of the mass matrix at the neutral
  configuration, kg or kg·m²) and ``f_max`` the highest frequency of the data (Hz; 4 kHz
  when unknown). A spring stiffer than ``K_MAX`` puts the joint's own mode ten times above
  the data (invisible); a damper above ``D_MAX`` damps a mode at ten times ``f_max``
  critically. So every default bound is finite and a fit cannot diverge to infinity.

* ``multiplier`` (a ``<mimic>`` joint's): ``a ± rel · max(|a|, s)`` (it may change sign):
  ``s`` is the length ``ℓ`` of the first body downstream with geometry (0.1 m without) for a
  translation per radian (a free pivot, :mod:`bondid.model.pivot`), else 1.

* ``rayleigh`` (``rayleigh.alpha``, ``rayleigh.beta``, ``rayleigh.eta``): ``[0, α_max]``,
  ``[0, β_max]`` and ``[0, 2]`` — ``α_max`` alone damps the model's lowest vibration mode
  critically, ``β_max`` alone a mode at ``f_max``, a loss factor of 2 every mode
  (:func:`bondid.linear.rayleigh.upper_bounds`); a relative width given for them
  (``--bound rayleigh=0.5``) bounds them as a damper's instead.

``rel`` maps a kind (``mass``, ``com``, ``inertia``, ``stiffness``, ``damping``), a parameter name
or a glob pattern (``x_stage.*``) to a fraction; the most specific entry wins (exact name, then
glob, then kind). ``absolute`` maps names or globs to ``(lo, hi)`` in SI units and overrides the
relative bounds.
"""

from __future__ import annotations

import fnmatch
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..consistency.hull import Hull, link_hull
from ..exceptions import ConfigError, ParameterError
from ..linear.parameter_map import RAYLEIGH_COMPONENTS
from ..model.document import UrdfDocument
from ..model.parameters import ParameterInfo, get_parameter, link_inertial, parameter_infos

#: Default relative half-width of the bounds, per parameter kind.
DEFAULT_REL: dict[str, float] = {
    "mass": 0.5,
    "com": 0.5,
    "inertia": 0.5,
    "stiffness": 0.5,
    "damping": 0.5,
    "gain": 9.0,  # a factor 1 + r either way: 10
    "mix": 10.0,  # a point's mix: ± r · max(|μ|, 1)
    "multiplier": 1.0,  # a mimic multiplier: ± r · max(|a|, its scale)
    "rayleigh": math.inf,  # [0, the coefficient that alone damps critically]
}

_DEFAULT_LENGTH = 0.1  # m, length scale of a link without geometry
_AXES = {"x": 0, "y": 1, "z": 2}
#: see the module docstring: the joint's own mode at 10 f_max, and critical damping there
STIFF_FACTOR = 100.0
DAMP_FACTOR = 20.0
#: ``f_max`` when the data's highest frequency is not known (Hz)
DEFAULT_F_MAX = 4000.0


def zero_value_upper(
    doc: UrdfDocument, joint: str, kind: str, f_max_hz: float, cache: dict | None = None
) -> float:
    """Upper bound of a stiffness or damping whose model value is 0 (module docstring);
    ``cache`` keeps the mass matrix between calls."""
    from ..linear.affine import build_affine_model

    cache = {} if cache is None else cache
    if "M" not in cache:
        am = build_affine_model(doc, {})
        cache["M"], cache["dofs"] = am.mass_matrix(), list(am.dofs)
    k = cache["dofs"].index(joint)
    w = 2.0 * np.pi * float(f_max_hz)
    mjj = float(cache["M"][k, k])
    if not mjj > 0:
        raise ConfigError(f"{doc.source or '<URDF>'}: joint {joint!r} moves no inertia")
    return STIFF_FACTOR * mjj * w**2 if kind == "stiffness" else DAMP_FACTOR * mjj * w


def infos_by_name(doc: UrdfDocument, names: Sequence[str]) -> list[ParameterInfo]:
    """The :class:`ParameterInfo` of each name, in order.

    Raises:
        ParameterError: a name the model does not have (the message lists valid forms).
        ConfigError: a name given twice, or one that asks for a kinematic joint placement.
    """
    table = {p.name: p for p in parameter_infos(doc)}
    out: list[ParameterInfo] = []
    seen: set[str] = set()
    where = doc.source or "<URDF>"
    for n in names:
        if n in seen:
            raise ConfigError(f"{where}: parameter {n!r} is listed twice")
        seen.add(n)
        info = table.get(n)
        if info is None:
            if any(t in n.split(".") for t in ("origin", "xyz", "rpy", "placement")):
                raise ConfigError(
                    f"{where}: {n!r}: fitting kinematic joint placements is not supported "
                    "(they enter M non-linearly); fit inertial, stiffness or damping parameters"
                )
            raise ParameterError(
                f"{where}: unknown parameter {n!r}; valid names look like LINK.mass, "
                "LINK.com.x, LINK.inertia.ixy, JOINT.stiffness, JOINT.damping "
                "(see bondid.model.parameter_names / select_parameters)"
            )
        out.append(info)
    return out


def link_hulls(doc: UrdfDocument, links: Sequence[str]) -> dict[str, Hull | None]:
    """Convex hull (link frame, m) of each link's collision geometry (None without geometry).

    Meshes (``package://``, ``file://``, relative) are resolved by
    :func:`bondid.model.packages.mesh_resolver` (package path, ``ROS_PACKAGE_PATH``, the
    URDF's folders, example-robot-data).
    """
    from ..model.packages import mesh_resolver

    resolve = mesh_resolver(doc)
    return {name: link_hull(doc.link(name), resolve, name=name) for name in links}


def _rel_for(info: ParameterInfo, rel: Mapping[str, float]) -> float:
    if info.name in rel:
        return float(rel[info.name])
    globs = [k for k in rel if k not in DEFAULT_REL and fnmatch.fnmatchcase(info.name, k)]
    if globs:
        return float(rel[max(globs, key=len)])
    if info.kind in rel:
        return float(rel[info.kind])
    return DEFAULT_REL[info.kind]


def default_bounds(
    doc: UrdfDocument,
    names: Sequence[str],
    rel: Mapping[str, float] | None = None,
    absolute: Mapping[str, tuple[float, float]] | None = None,
    f_max_hz: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds ``(n,)``, ``(n,)`` (SI units) of the named parameters.

    Args:
        doc: the model whose current values the relative bounds are taken around.
        names: parameter names (URDF form, e.g. ``x_stage.mass``), length ``n``.
        rel: fraction per kind, name or glob (see the module docstring); missing kinds use
            :data:`DEFAULT_REL`.
        absolute: ``(lo, hi)`` per name or glob, overriding the relative bounds.
        f_max_hz: the data's highest frequency (Hz) for the bounds of zero-valued stiffness
            and damping (default :data:`DEFAULT_F_MAX`).

    Raises:
        ParameterError: unknown name. ConfigError: a negative fraction, or ``lo > hi``.
    """
    rel = dict(rel or {})
    for k, v in rel.items():
        if not np.isfinite(v) or v < 0:
            raise ConfigError(f"bounds: relative width {float(v)!r} for {k!r}: give a value >= 0")
    infos = infos_by_name(doc, names)
    hulls = link_hulls(doc, sorted({i.owner for i in infos if i.kind == "com"}))
    f_max = DEFAULT_F_MAX if f_max_hz is None else f_max_hz
    cache: dict = {}
    pairs = [_relative_bound(doc, info, _rel_for(info, rel), hulls, f_max, cache) for info in infos]
    lo = np.array([a for a, _ in pairs], dtype=float).reshape(-1)
    hi = np.array([b for _, b in pairs], dtype=float).reshape(-1)
    _apply_absolute(infos, absolute or {}, lo, hi)
    return lo, hi


def _downstream_length(doc: UrdfDocument, joint: str) -> float:
    """The size ``ℓ`` (m) of the first link below ``joint`` with geometry (the bounding-box
    diagonal of its hull), else :data:`_DEFAULT_LENGTH`."""
    child = doc.joint(joint).child
    while True:
        h = link_hulls(doc, [child])[child]
        if h is not None:
            return float(h.size)
        below = [j for j in doc.robot.joints if j.parent == child]
        if not below:
            return _DEFAULT_LENGTH
        child = below[0].child


def _relative_bound(
    doc: UrdfDocument, info: Any, r: float, hulls: Mapping[str, Any], f_max: float, cache: dict
) -> tuple[float, float]:
    """``(lo, hi)`` of one parameter for the relative width ``r`` (module docstring)."""
    v = get_parameter(doc, info.name)
    if info.kind == "mass":
        return max(0.0, v - r * abs(v)), v + r * abs(v)
    if info.kind == "com":
        h = hulls[info.owner]
        half = r * max(abs(v), 0.1 * (h.size if h is not None else _DEFAULT_LENGTH))
        return v - half, v + half
    if info.kind == "inertia":
        _, _, I_c = link_inertial(doc, info.owner)
        comp = str(info.component)  # ixx … izz
        ia, ib = _AXES[comp[1]], _AXES[comp[2]]
        if ia != ib:  # a product: relative to the largest it can be (module docstring)
            S = 0.5 * float(np.trace(I_c)) * np.eye(3) - I_c  # second moment about the CoM
            half = r * max(abs(v), float(np.sqrt(max(S[ia, ia], 0.0) * max(S[ib, ib], 0.0))))
        else:
            half = r * max(abs(v), 0.1 * abs(float(np.trace(I_c)) / 3.0))
        return v - half, v + half
    if info.kind == "gain":  # relative r: a factor 1 + r either way (sign kept)
        a, b = sorted((v / (1.0 + r), v * (1.0 + r)))
        return a, b
    if info.kind == "mix":  # may change sign: room around 0 as around the value
        half = r * max(abs(v), 1.0)
        return v - half, v + half
    if info.kind == "multiplier":  # may change sign, as a mix
        s = _downstream_length(doc, info.owner) if info.unit == "m/rad" else 1.0
        half = r * max(abs(v), s)
        return v - half, v + half
    if info.kind == "rayleigh" and (math.isinf(r) or v == 0.0):
        return 0.0, _rayleigh_upper(doc, str(info.component), f_max, cache)
    if v == 0.0:  # stiffness, damping
        return 0.0, zero_value_upper(doc, info.owner, info.kind, f_max, cache)
    return max(0.0, v - r * abs(v)), v + r * abs(v)


def _rayleigh_upper(doc: UrdfDocument, component: str, f_max: float, cache: dict) -> float:
    """``α_max`` or ``β_max`` of the model (module docstring); ``cache`` keeps them."""
    if "rayleigh" not in cache:
        from ..linear.affine import build_affine_model
        from ..linear.rayleigh import upper_bounds

        cache["rayleigh"] = upper_bounds(build_affine_model(doc, {}), f_max)
    return float(cache["rayleigh"][RAYLEIGH_COMPONENTS.index(component)])


def _apply_absolute(
    infos: Sequence[Any],
    absolute: Mapping[str, tuple[float, float]],
    lo: np.ndarray,
    hi: np.ndarray,
) -> None:
    """Overwrite ``lo``/``hi`` ``(n,)`` in place with the ``(lo, hi)`` given per name or glob."""
    for key, (a, b) in absolute.items():
        hits = [j for j, i in enumerate(infos) if fnmatch.fnmatchcase(i.name, key)]
        if not hits:
            raise ConfigError(f"bounds: {key!r} matches none of the fitted parameters")
        if not a <= b:
            raise ConfigError(f"bounds: {key!r} has lower {float(a):g} > upper {float(b):g}")
        lo[hits], hi[hits] = float(a), float(b)

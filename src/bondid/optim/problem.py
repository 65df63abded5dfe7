"""The fit problem, built once: :class:`FitProblem`.

Built from ``(model, data sets, free names, bounds, cost options)``, it owns

* the linearisations (one :class:`~bondid.linear.affine.AffineModel` per data set, inside its
  :class:`~bondid.cost.FrfProblem`),
* the decision vector ``z`` (:class:`~.layout.Layout`: log-Cholesky coordinates per fitted
  body, scaled joint parameters and gains) with its start ``z0`` and bounds ``lbz``, ``ubz``,
* the residual ``r(z)`` with its exact Jacobian (:class:`~.evaluator.Evaluator`),
* the physical-consistency constraints ``g(z)`` and their labels (:meth:`FitProblem.constraints`,
  returned as a :class:`~.constraints.Constraints` value), and the CasADi functions IPOPT
  is given (:meth:`FitProblem.nlp`),

and can be restricted to a subset of the names, to other bands, or to another residual kind
without linearising again (:meth:`FitProblem.restrict`). Extra (candidate) parameters are just
more names of the model; several joint parameters can share one variable (``ties``).
:func:`bondid.optim.ipopt.solve` solves it; :mod:`bondid.optim.search` runs schedules of such
solves.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ..consistency.hull import Hull
from ..cost.modifier import FrfModifier
from ..cost.problem import CostOptions, FrfProblem
from ..data.measurement import FrfData
from ..exceptions import ConfigError, ParameterError
from ..model.document import UrdfDocument
from ..model.parameters import ParameterInfo, get_parameters, parameter_infos, set_parameter
from .constraints import Constraints, layout_constraints
from .evaluator import Evaluator, ExtraRows
from .free_columns import movable
from .layout import Layout
from .modified import ModifiedLayout
from .nlp import Nlp
from .tied import TiedParameters, check_ties, fitted_document

#: ``restrict(bands=KEEP)``: keep the problem's bands
KEEP: Any = object()
#: a parameter tie: ``{leader: [(member, factor), ...]}`` — each member = factor × leader
Ties = Mapping[str, Sequence[tuple[str, float]]]


class FitProblem:
    """A bounded, physically constrained least-squares fit of named model parameters.

    Args:
        doc: the model; not modified. Names not in ``names`` keep its values.
        datasets: measured FRFs, one linearisation each (at its operating point).
        names: free parameters (URDF form, e.g. ``x_stage.mass``), length ``n``.
        options: cost options (default: complex-log L2, all channels and frequencies).
        lower, upper: bounds ``(n,)`` in SI units (default
            :func:`bondid.optim.bounds.default_bounds`; ±inf allowed).
        start: starting values ``(n,)`` (default: the model's), clipped to the bounds; each
            fitted body is projected into the feasible set when it is not (see ``notes``).
        use_hull: constrain each fitted body's CoM to its collision geometry's convex hull.
        ties: joint stiffness/damping parameters driven by a free one:
            ``{leader: [(member, factor), ...]}`` sets ``member = factor · leader``; members
            are not in ``names`` and not fitted on their own.
        extra_rows: builds residual rows appended to the data's for each problem made from
            this one (here and by :meth:`restrict`), e.g. a prior toward the model's values:
            ``extra_rows(problem) -> rows | None`` with ``rows(z) -> (r (m,), J (m, size))``
            and ``rows.size == m`` (:class:`~.evaluator.ExtraRows`); it may tighten
            ``problem.lbz``/``ubz`` and extend ``var_labels`` and ``notes``. The reported
            costs stay the data's alone.
        modifier: an FRF modifier ``H ← G(ω; θ) ⊙ (L H R)`` (:class:`bondid.cost.modifier.
            FrfModifier`, e.g. a sensor delay) whose parameters θ are fitted too, in ``ln θ``
            (or linearly, its signed ones) after the named ones in ``z`` (:mod:`.modified`);
            read them with :meth:`theta`.

    Raises:
        ParameterError: an unknown name or a link that does not move.
        ConfigError: no name, a repeated name, a kinematic placement, bad bounds or start,
            bad ties, or no data left by the options.

    Attributes:
        doc, names, options, frf (the :class:`~bondid.cost.FrfProblem`), lower, upper,
        initial (the start, clipped), layout, evaluator, z0, lbz, ubz, notes.
    """

    def __init__(
        self,
        doc: UrdfDocument,
        datasets: Sequence[FrfData],
        names: Sequence[str],
        *,
        options: CostOptions | None = None,
        lower: np.ndarray | None = None,
        upper: np.ndarray | None = None,
        start: np.ndarray | None = None,
        use_hull: bool = True,
        ties: Ties | None = None,
        modifier: FrfModifier | None = None,
        extra_rows: Callable[[FitProblem], ExtraRows | None] | None = None,
    ):
        from .bounds import infos_by_name

        names = list(names)
        if not names:
            raise ConfigError("no parameters to fit; give at least one name")
        infos = infos_by_name(doc, names)
        lo, hi = _bounds(doc, datasets, names, infos, lower, upper)
        p0 = get_parameters(doc, names) if start is None else np.asarray(start, dtype=float)
        if p0.shape != (len(names),) or not np.all(np.isfinite(p0)):
            raise ConfigError(f"start must be {len(names)} finite values, got shape {p0.shape}")
        frf = FrfProblem(doc, datasets, options, modifier=modifier)
        for info in infos:
            if info.is_inertial and info.owner not in frf.affines[0].bodies:
                raise ParameterError(
                    f"{info.name}: link {info.owner!r} does not move; cannot fit it"
                )
        ties = check_ties(doc, names, ties or {})
        theta0 = None if modifier is None else np.array(modifier.start, float)
        self._extra_rows = extra_rows
        self._setup(doc, frf, infos, lo, hi, p0, use_hull, {}, ties, theta0)

    # -- construction ---------------------------------------------------------------------
    def _setup(
        self,
        doc: UrdfDocument,
        frf: FrfProblem,
        infos: list[ParameterInfo],
        lo: np.ndarray,
        hi: np.ndarray,
        p0: np.ndarray,
        use_hull: bool,
        hulls: dict[str, Hull | None],
        ties: dict[str, list[tuple[str, float]]],
        theta0: np.ndarray | None = None,
    ) -> None:
        from .bounds import link_hulls

        self.doc, self.frf, self.infos = doc, frf, infos
        self.names = [i.name for i in infos]
        self.lower, self.upper, self.use_hull, self.ties = lo, hi, use_hull, ties
        self.notes: list[str] = []
        bad = [self.names[i] for i in np.flatnonzero(~(lo <= hi))]
        if bad:
            raise ConfigError(f"lower bound > upper bound (or NaN) for {', '.join(bad)}")
        for i, info in enumerate(infos):
            if info.kind == "mass" and hi[i] <= 0:
                raise ConfigError(f"{info.name}: upper bound {hi[i]:g} kg leaves no positive mass")
        clipped = np.clip(p0, lo, hi)
        if np.any(clipped != p0):
            outside = [self.names[i] for i in np.flatnonzero(clipped != p0)]
            self.notes.append(f"start outside the bounds, clipped: {', '.join(outside)}")
        self.initial = clipped
        owners = {p.name: p.owner for p in parameter_infos(doc) if p.is_inertial}
        tied = {owners[m] for ms in ties.values() for m, _ in ms if m in owners}
        links = sorted({i.owner for i in infos if i.is_inertial} | tied)
        missing = [k for k in links if k not in hulls]
        self._hulls = dict(hulls)
        self._hulls.update(link_hulls(doc, missing) if use_hull else dict.fromkeys(missing))
        for link in links:
            if use_hull and self._hulls[link] is None:
                self.notes.append(
                    f"{link}: no collision or visual geometry, so no CoM-in-hull constraint"
                )
        mine = {k: self._hulls[k] for k in links}
        self.layout = Layout(doc, frf.affines[0], infos, mine, ties)
        self.z0 = self.layout.start(doc, clipped, lo, hi)
        self.notes.extend(self.layout.notes)
        self.lbz, self.ubz, self.var_labels = self.layout.variable_bounds(lo, hi)
        self.model: Layout | ModifiedLayout = self.layout
        self._theta0: np.ndarray | None = theta0
        if frf.modifier is not None and theta0 is not None:
            self._add_modifier(frf.modifier, theta0)
        self.rows = None if self._extra_rows is None else self._extra_rows(self)
        self.evaluator = Evaluator(
            frf, self.model, prior=self.rows, free=movable(self.lbz, self.ubz)
        )
        self._constraints: Constraints | None = None
        self._nlp: dict[str, Nlp] = {}

    def restrict(
        self,
        names: Sequence[str] | None = None,
        *,
        start: np.ndarray | None = None,
        bands: Sequence[tuple[float, float]] | None = KEEP,
        kind: str | None = None,
        norm: str | None = None,
        lower: np.ndarray | None = None,
        upper: np.ndarray | None = None,
        theta: np.ndarray | None = None,
    ) -> FitProblem:
        """A problem over the same linearisations with another selection (nothing is
        linearised again; the data selection and the decision vector are rebuilt).

        Args:
            names: the free subset (default: all of this problem's names, in this order);
                the others are held at ``start``.
            start: values ``(n,)`` of THIS problem's names (default ``initial``): the held
                values, and the start of the free ones.
            bands: frequency bands (Hz) to fit (None = all; default: keep).
            kind, norm: another residual kind / norm (default: keep).
            lower, upper: bounds of the subset ``(len(names),)`` (default: this problem's).
            theta: the FRF modifier's start ``(n_θ,)`` (default: this problem's).
        """
        x = self.initial if start is None else np.asarray(start, dtype=float)
        sub = self.names if names is None else list(names)
        unknown = [n for n in sub if n not in self.names]
        if unknown:
            raise ConfigError(f"restrict: {', '.join(unknown)} not among the problem's names")
        idx = [self.names.index(n) for n in sub]
        changes: dict[str, Any] = {}
        if bands is not KEEP:
            changes["bands"] = None if bands is None else list(bands)
        if kind is not None:
            changes["kind"] = kind
        if norm is not None:
            changes["norm"] = norm
        # the same options keep the point selection (nothing is selected again)
        frf = (
            self.frf.with_options(dataclasses.replace(self.options, **changes))
            if changes
            else self.frf
        )
        doc = self.document_at(x)
        frf = frf.moved(self.parameter_map(), x, doc)
        out = object.__new__(FitProblem)
        out._extra_rows = self._extra_rows
        lo = self.lower[idx] if lower is None else np.asarray(lower, dtype=float)
        hi = self.upper[idx] if upper is None else np.asarray(upper, dtype=float)
        ties = {k: v for k, v in self.ties.items() if k in sub}
        infos = [self.infos[i] for i in idx]
        th = self._theta0 if theta is None else np.asarray(theta, dtype=float)
        out._setup(doc, frf, infos, lo, hi, x[idx], self.use_hull, self._hulls, ties, th)
        return out

    def _add_modifier(self, modifier: FrfModifier, theta0: np.ndarray) -> None:
        """Append the modifier's entries to ``z`` (``ln θ``, or ``(θ − θ₀)/s`` for its
        linear-scale parameters: :meth:`~bondid.cost.modifier.FrfModifier.u_of`; start,
        bounds, labels)."""
        theta0 = np.clip(theta0, modifier.lower, modifier.upper)
        self._theta0 = theta0
        self.model = ModifiedLayout(self.layout, theta0, modifier)
        n = self.layout.size
        lo = modifier.u_of(np.asarray(modifier.lower, float), theta0)
        hi = modifier.u_of(np.asarray(modifier.upper, float), theta0)
        self.z0 = np.concatenate([self.z0, np.zeros(theta0.size)])
        self.lbz, self.ubz = np.concatenate([self.lbz, lo]), np.concatenate([self.ubz, hi])
        self.var_labels = self.var_labels + [(m, n + k) for k, m in enumerate(modifier.names)]

    def theta(self, z: np.ndarray) -> np.ndarray:
        """The FRF modifier's parameters ``(n_θ,)`` at ``z`` (empty without a modifier)."""
        if isinstance(self.model, ModifiedLayout):
            return self.model.modifier_values(z)
        return np.zeros(0)

    # -- sizes and options ----------------------------------------------------------------
    @property
    def options(self) -> CostOptions:
        return self.frf.options

    @property
    def size(self) -> int:
        """Size of the decision vector ``z``."""
        return int(self.model.size)

    @property
    def n_residuals(self) -> int:
        return self.frf.n_residuals

    @property
    def data_span_hz(self) -> tuple[float, float]:
        """Lowest and highest frequency of the data sets (Hz), whatever the bands."""
        freqs = [d.freq_hz for d in self.frf.datasets]
        return min(float(f.min()) for f in freqs), max(float(f.max()) for f in freqs)

    # -- evaluation (decision vector) -----------------------------------------------------
    def residual(self, z: np.ndarray) -> np.ndarray:
        """Scaled residual at ``z`` (NaN where the model is invalid): the data's
        ``(n_residuals,)``, then the extra rows if any."""
        return self.evaluator.residual(z)

    def residual_and_jacobian(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual (as :meth:`residual`) and its exact Jacobian ``(·, size)`` at ``z``."""
        return self.evaluator.residual_and_jacobian(z)

    def cost(self, z: np.ndarray) -> float:
        """The objective ``‖r(z)‖²`` (the data's and the extra rows')."""
        return self.evaluator.cost(z)

    def data_cost(self, z: np.ndarray) -> float:
        """The data's part of the cost (what is reported)."""
        r = self.residual(z)[: self.n_residuals]
        return float(r @ r)

    def constraints(self) -> Constraints:
        """The constraints ``g(z)`` with bounds and labels (built once, then cached)."""
        if self._constraints is None:
            import casadi

            zsym = casadi.SX.sym("z", self.size)
            g, lbg, ubg, labels = layout_constraints(self.layout, zsym, self.lower, self.upper)
            self._constraints = Constraints(zsym, g, lbg, ubg, tuple(labels))
        return self._constraints

    def nlp(self, constraint_hessian: str = "convexified") -> Nlp:
        """The CasADi functions IPOPT is given (:class:`~.nlp.Nlp`), cached per
        ``constraint_hessian``."""
        if constraint_hessian not in self._nlp:
            self._nlp[constraint_hessian] = Nlp(
                self.evaluator, self.constraints(), constraint_hessian
            )
        return self._nlp[constraint_hessian]

    # -- named values ---------------------------------------------------------------------
    def values(self, z: np.ndarray) -> np.ndarray:
        """The named parameters ``(n,)`` at ``z`` (SI units), clipped to the bounds."""
        return np.clip(self.layout.named(z), self.lower, self.upper)

    def document(self, z: np.ndarray) -> UrdfDocument:
        """A copy of the model with the values at ``z`` (fixed parameters keep theirs)."""
        return fitted_document(self.doc, self.layout, z, self.values(z))

    def document_at(self, x: np.ndarray) -> UrdfDocument:
        """A copy of the model with the named values ``x`` ``(n,)`` (and their tied members)."""
        out = self.doc.copy()
        for name, v in zip(self.names, np.asarray(x, dtype=float), strict=True):
            for member, factor in [(name, 1.0), *self.ties.get(name, ())]:
                w = factor * float(v)
                set_parameter(out, member, max(w, 0.0) if member.endswith(_NONNEG) else w)
        return out

    def parameter_map(self) -> TiedParameters:
        """The named parameters (with their ties) as a parameter model of ``frf``."""
        return TiedParameters(self.doc, self.frf.affines[0], self.names, self.ties)

    def named_residual_and_jacobian(
        self, z: np.ndarray, doc: UrdfDocument | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Residual ``(n_r,)`` and Jacobian ``(n_r, n)`` in the named parameters (SI units) at
        the solution ``z`` (what the parameter statistics are computed from); ``doc``: the
        model at ``z`` when the caller has it (:meth:`document`), else built here."""
        doc = self.document(z) if doc is None else doc
        frf = self.frf.moved(self.model, np.asarray(z, dtype=float), doc)
        pmap = TiedParameters(doc, frf.affines[0], self.names, self.ties)
        return frf.residual_and_jacobian(pmap, get_parameters(doc, self.names))

    def phase_wall_fraction(self, z: np.ndarray) -> float:
        """:meth:`bondid.cost.FrfProblem.phase_wall_fraction` at ``z``."""
        return self.frf.phase_wall_fraction(self.model, np.asarray(z, dtype=float))


_NONNEG = (".stiffness", ".damping", ".mass", "rayleigh.alpha", "rayleigh.beta", "rayleigh.eta")


def _bounds(
    doc: UrdfDocument,
    datasets: Sequence[FrfData],
    names: list[str],
    infos: list[ParameterInfo],
    lower: np.ndarray | None,
    upper: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray]:
    """The bounds given, completed by the defaults, checked for shape."""
    from .bounds import default_bounds

    if lower is None or upper is None:
        f_max = max((float(np.max(d.freq_hz)) for d in datasets), default=None)
        dlo, dhi = default_bounds(doc, names, f_max_hz=f_max)
        lower = dlo if lower is None else lower
        upper = dhi if upper is None else upper
    lo = np.asarray(lower, dtype=float).reshape(-1)
    hi = np.asarray(upper, dtype=float).reshape(-1)
    n = len(infos)
    if lo.shape != (n,) or hi.shape != (n,):
        raise ConfigError(f"bounds have shapes {lo.shape}, {hi.shape}; expected ({n},) each")
    return lo, hi

"""Mode shapes in Meshcat: the machine's URDF geometry, a mode animated, nominal vs fitted.

The mode is shown as ``q(θ) = q0 ⊕ s · Re(φ e^{jθ})``, θ over one period (``⊕`` =
``pinocchio.integrate``), slowed down to ``period_s`` seconds per cycle. The scale ``s`` makes
the point that moves most travel ``amplitude`` × the machine's size (the diagonal of the
bounding box of its geometry at q0). A second machine (the fitted model) is drawn beside the
first, offset along +y, in the same camera view.

Meshcat runs its server as a subprocess (ZMQ + websocket on 127.0.0.1). :class:`ModeScene`
owns it and kills it on :meth:`ModeScene.close` (also a context manager). The static page
(``static_html``) embeds Meshcat's bundled viewer JavaScript, the geometry and the animation,
so it plays with no network.
"""

from __future__ import annotations

import contextlib
import html as html_lib
import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..atomic import write_text_atomic
from ..exceptions import DependencyError, ModelError
from ..model.document import UrdfDocument
from .analysis import Mode

FITTED_COLOR = (0.95, 0.55, 0.1, 1.0)
"""RGBA of the fitted machine (the nominal one keeps its URDF colours)."""
_REPETITIONS = 1_000_000


@dataclass
class Machine:
    """One machine in the scene: Pinocchio model, geometry and its Meshcat node name."""

    name: str
    model: Any  # pinocchio.Model
    geom: Any  # pinocchio.GeometryModel (visual, or collision when there is no <visual>)
    q0: np.ndarray
    offset: np.ndarray
    dofs: tuple[str, ...]

    def dof_vector(self, shape: np.ndarray, dofs: tuple[str, ...]) -> np.ndarray:
        """``shape`` (len(dofs),) re-ordered into this model's velocity order; missing = 0."""
        out = np.zeros(self.model.nv, dtype=complex)
        for j, name in enumerate(dofs):
            if name in self.dofs:
                out[self.dofs.index(name)] = shape[j]
        return out

    def placements(self, q: np.ndarray) -> list[np.ndarray]:
        """World 4×4 transforms of every geometry object at ``q`` (machine frame)."""
        import pinocchio as pin

        data = self.model.createData()
        gdata = pin.GeometryData(self.geom)
        pin.forwardKinematics(self.model, data, q)
        pin.updateGeometryPlacements(self.model, data, self.geom, gdata)
        return [np.asarray(gdata.oMg[i].homogeneous) for i in range(self.geom.ngeoms)]

    def radii(self) -> np.ndarray:
        """Bounding-sphere radius [m] of each geometry object (0.05 m when unknown)."""
        out = []
        for obj in self.geom.geometryObjects:
            try:
                obj.geometry.computeLocalAABB()
                out.append(float(obj.geometry.aabb_radius))
            except Exception:
                out.append(0.05)
        return np.asarray(out)

    def q_at(self, dq: np.ndarray) -> np.ndarray:
        import pinocchio as pin

        return np.asarray(pin.integrate(self.model, self.q0, np.asarray(dq, dtype=float)))


def load_machine(
    doc: UrdfDocument, q0: np.ndarray, name: str, offset: np.ndarray | None = None
) -> Machine:
    """Pinocchio model and visual geometry of ``doc`` (primitives and meshes from the URDF)."""
    import pinocchio as pin

    from ..model.packages import text_with_resolved_meshes

    where = doc.source or "<URDF>"
    model = doc.build_pinocchio_model()
    text = text_with_resolved_meshes(doc)
    try:
        geom = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.VISUAL)
        if geom.ngeoms == 0:
            geom = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.COLLISION)
    except Exception as exc:
        raise ModelError(f"{where}: Pinocchio could not build the geometry ({exc})") from exc
    if geom.ngeoms == 0:
        raise ModelError(f"{where}: the URDF has no <visual> or <collision> geometry to draw")
    q = np.asarray(q0, dtype=float)
    if q.shape != (model.nq,):
        raise ModelError(f"{where}: configuration has {q.size} entries, the model nq={model.nq}")
    dofs = [""] * model.nv
    for jid in range(1, model.njoints):
        jm = model.joints[jid]
        if jm.nv == 1:
            dofs[jm.idx_v] = model.names[jid]
    off = np.zeros(3) if offset is None else np.asarray(offset, dtype=float)
    return Machine(name, model, geom, q, off, tuple(dofs))


def bounding_box(machine: Machine) -> tuple[np.ndarray, np.ndarray]:
    """(lower (3,), upper (3,)) corners [m] of the geometry at q0, in the machine's frame.

    Uses each object's local axis-aligned box (its bounding sphere when unavailable).
    """
    pts = []
    for obj, T, r in zip(
        machine.geom.geometryObjects, machine.placements(machine.q0), machine.radii(), strict=True
    ):
        try:
            obj.geometry.computeLocalAABB()
            a = np.asarray(obj.geometry.aabb_local.min_, dtype=float)
            b = np.asarray(obj.geometry.aabb_local.max_, dtype=float)
        except Exception:
            a, b = np.full(3, -r), np.full(3, r)
        corners = np.array(
            [[x, y, z] for x in (a[0], b[0]) for y in (a[1], b[1]) for z in (a[2], b[2])]
        )
        pts.append(corners @ T[:3, :3].T + T[:3, 3])
    allp = np.vstack(pts)
    return allp.min(axis=0), allp.max(axis=0)


def mode_scale(machine: Machine, phi: np.ndarray, amplitude: float, size: float) -> float:
    """Scale ``s`` so the largest displacement over a cycle is ``amplitude · size`` [m].

    Displacement of a geometry object = |Δ position| + radius · |Δ rotation angle|, measured
    at a small trial scale (linear regime) over 16 phases.
    """
    import pinocchio as pin

    if not np.any(phi):
        return 0.0
    eps = 1e-6 / float(np.max(np.abs(phi)))
    T0 = machine.placements(machine.q0)
    radii = machine.radii()
    worst = 0.0
    for theta in np.linspace(0, 2 * math.pi, 16, endpoint=False):
        T = machine.placements(machine.q_at(eps * np.real(phi * np.exp(1j * theta))))
        for t0, t1, r in zip(T0, T, radii, strict=True):
            dp = float(np.linalg.norm(t1[:3, 3] - t0[:3, 3]))
            dr = float(np.linalg.norm(pin.log3(t0[:3, :3].T @ t1[:3, :3])))
            worst = max(worst, dp + r * dr)
    if worst <= 0.0:
        return 0.0
    return amplitude * size * eps / worst


class ModeScene:
    """A Meshcat scene (own server subprocess) with machines and one mode animation.

    Args:
        quiet: suppress Meshcat's own prints (the URL line) while starting.

    Use as a context manager, or call :meth:`close`; the server is killed either way.
    """

    def __init__(self, *, quiet: bool = True) -> None:
        try:
            import meshcat
        except ImportError as exc:  # pragma: no cover - meshcat is a dependency
            raise DependencyError(f"meshcat is not installed ({exc})") from exc
        sink = io.StringIO()
        with contextlib.redirect_stdout(sink) if quiet else contextlib.nullcontext():
            self.viewer = meshcat.Visualizer()
        self.machines: list[Machine] = []
        self._viz: dict[str, Any] = {}

    # -- lifecycle ------------------------------------------------------------------
    @property
    def url(self) -> str:
        """The viewer's local web address (``http://127.0.0.1:PORT/static/``)."""
        return str(self.viewer.url())

    @property
    def server_pid(self) -> int | None:
        proc = getattr(self.viewer.window, "server_proc", None)
        return None if proc is None else int(proc.pid)

    def close(self) -> None:
        """Kill the Meshcat server subprocess and close the ZMQ socket."""
        window = self.viewer.window
        proc = getattr(window, "server_proc", None)
        if proc is not None and proc.poll() is None:
            proc.kill()
            proc.wait()
            for stream in (proc.stdout, proc.stderr):
                if stream is not None:
                    stream.close()
        sock = getattr(window, "zmq_socket", None)
        if sock is not None:
            sock.close(linger=0)

    def __enter__(self) -> ModeScene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- content --------------------------------------------------------------------
    def add_machine(self, machine: Machine, color: tuple[float, ...] | None = None) -> None:
        """Draw ``machine`` at its q0 under node ``machine.name``, shifted by its offset."""
        from pinocchio.visualize import MeshcatVisualizer

        viz = MeshcatVisualizer(machine.model, machine.geom, machine.geom)
        viz.initViewer(viewer=self.viewer)
        rgba = None if color is None else np.asarray(color, dtype=float)
        viz.loadViewerModel(rootNodeName=machine.name, visual_color=rgba)
        viz.display(machine.q0)
        T = np.eye(4)
        T[:3, 3] = machine.offset
        self.viewer[machine.name].set_transform(T)
        self.machines.append(machine)
        self._viz[machine.name] = viz

    def animate(
        self,
        shapes: list[tuple[Machine, np.ndarray, float]],
        *,
        period_s: float = 2.0,
        fps: int = 30,
    ) -> None:
        """Loop one cycle of each ``(machine, φ (nv,) complex, scale)``, in step.

        ``period_s`` is the displayed duration of one cycle (the real one may be ms).
        """
        import meshcat.animation as mca
        import pinocchio as pin

        n_frames = max(round(period_s * fps), 4)
        anim = mca.Animation(default_framerate=fps)
        for machine, phi, scale in shapes:
            viz = self._viz[machine.name]
            names = [
                viz.getViewerNodeName(o, pin.GeometryType.VISUAL)
                for o in machine.geom.geometryObjects
            ]
            for k in range(n_frames + 1):
                theta = 2 * math.pi * k / n_frames
                q = machine.q_at(scale * np.real(phi * np.exp(1j * theta)))
                with anim.at_frame(self.viewer, k) as frame:
                    for name, T in zip(names, machine.placements(q), strict=True):
                        frame[name].set_transform(T)
        self.viewer.set_animation(anim, play=True, repetitions=_REPETITIONS)

    def frame_camera(self) -> None:
        """Aim the default camera at all machines from the front-right, above.

        Meshcat 0.3.2's orbit controls look at the world origin, so the machines are moved
        (their root nodes shifted) to put the centre of their bounding box there.
        """
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for m in self.machines:
            a, b = bounding_box(m)
            lo, hi = np.minimum(lo, a + m.offset), np.maximum(hi, b + m.offset)
        if not self.machines:
            lo, hi = -np.ones(3), np.ones(3)
        centre = 0.5 * (lo + hi)
        size = float(np.linalg.norm(hi - lo)) or 1.0
        for m in self.machines:
            T = np.eye(4)
            T[:3, 3] = m.offset - centre
            self.viewer[m.name].set_transform(T)
        self.viewer["/Grid"].set_property("visible", False)
        self.viewer["/Axes"].set_property("visible", False)
        d = np.array([1.0, -0.7, 0.65])
        d = 0.95 * size * d / np.linalg.norm(d)
        # the camera node is y-up (three.js): world (x, y, z) -> (x, z, -y)
        self.viewer["/Cameras/default/rotated/<object>"].set_property(
            "position", [float(d[0]), float(d[2]), float(-d[1])]
        )

    def static_html(self, title: str = "bondid modes", caption: str = "") -> str:
        """The whole scene as one self-contained HTML page (viewer JS embedded)."""
        page = str(self.viewer.static_html())
        safe_title = html_lib.escape(title)
        page = page.replace("<title>MeshCat</title>", f"<title>{safe_title}</title>", 1)
        if caption:
            box = (
                '<div style="position:absolute;left:8px;top:8px;z-index:10;padding:6px 10px;'
                "background:rgba(255,255,255,0.85);font:14px sans-serif;border-radius:4px;"
                f'max-width:60vw">{caption}</div>'
            )
            page = page.replace("<body>", "<body>" + box, 1)
        return page


def machine_size(machines: list[Machine]) -> float:
    """Diagonal [m] of the bounding box of the first machine (the size unit of amplitude)."""
    lo, hi = bounding_box(machines[0])
    return float(np.linalg.norm(hi - lo)) or 1.0


def build_mode_scene(
    doc: UrdfDocument,
    q0: np.ndarray,
    mode: Mode,
    dofs: tuple[str, ...],
    *,
    amplitude: float = 0.05,
    fitted: tuple[UrdfDocument, np.ndarray, Mode, tuple[str, ...]] | None = None,
    period_s: float = 2.0,
    quiet: bool = True,
) -> ModeScene:
    """A :class:`ModeScene` with ``mode`` of ``doc`` animated (and the fitted one beside it).

    Args:
        doc: the nominal model; q0: its configuration ``(nq,)``.
        mode: the mode to show; dofs: DOF names of ``mode.shape``.
        amplitude: largest displacement as a fraction of the machine's size.
        fitted: ``(doc, q0, mode, dofs)`` of the fitted model, drawn offset along +y.
        period_s: displayed seconds per cycle.

    The caller must close the returned scene (it owns a server subprocess).
    """
    nominal = load_machine(doc, q0, "nominal")
    pairs: list[tuple[Machine, Mode, tuple[str, ...]]] = [(nominal, mode, dofs)]
    if fitted is not None:
        fdoc, fq0, fmode, fdofs = fitted
        lo, hi = bounding_box(nominal)
        shift = np.array([0.0, 1.25 * float(hi[1] - lo[1]), 0.0])
        pairs.append((load_machine(fdoc, fq0, "fitted", shift), fmode, fdofs))
    size = machine_size([nominal])
    scene = ModeScene(quiet=quiet)
    try:
        shapes = []
        for i, (machine, m, names) in enumerate(pairs):
            scene.add_machine(machine, None if i == 0 else FITTED_COLOR)
            phi = machine.dof_vector(m.shape, names)
            shapes.append((machine, phi, mode_scale(machine, phi, amplitude, size)))
        scene.animate(shapes, period_s=period_s)
        scene.frame_camera()
    except BaseException:
        scene.close()
        raise
    return scene


def mode_caption(mode: Mode, fitted: Mode | None = None) -> str:
    """A short HTML caption naming the mode(s) shown."""

    def text(m: Mode) -> str:
        if m.kind == "rigid":
            return f"mode {m.index}: rigid body ({html_lib.escape(m.dominant_dof)})"
        return (
            f"mode {m.index}: {m.f_hz:.2f} Hz, ζ = {m.zeta:.4f}"
            f" (main DOF {html_lib.escape(m.dominant_dof)})"
        )

    out = "nominal — " + text(mode)
    if fitted is not None:
        out += "<br>fitted (orange, right) — " + text(fitted)
    return out + "<br><small>animation slowed to one cycle per 2 s; drag to orbit</small>"


def write_mode_html(path: str | Path, scene: ModeScene, title: str, caption: str) -> Path:
    """Write the scene's static page atomically to ``path``."""
    return write_text_atomic(path, scene.static_html(title, caption))

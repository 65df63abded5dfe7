"""Draw a URDF model's collision geometry at q = 0 (neutral) as a labelled 3-D picture.

Usage::

    python tools/draw_model.py --model urdf/bonder.urdf --out urdf/bonder.png

Link placements come from Pinocchio forward kinematics at the neutral configuration; the
geometry (boxes, cylinders, spheres; meshes are skipped) is read with yourdfpy. Each link
with geometry is drawn in its `<visual>` colour (a fixed palette when it has none) and
labelled at its frame origin; its centre of mass is marked with a black dot.
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path
from typing import Any

import numpy as np

_PALETTE = ["#9e9e9e", "#d32f2f", "#7b1fa2", "#1976d2", "#388e3c", "#f57c00"]


def box_faces(size: np.ndarray, pose: np.ndarray) -> list[np.ndarray]:
    """Faces of a box.

    Args:
        size: (3,) edge lengths [m].
        pose: (4, 4) homogeneous transform of the box centre in the world frame.

    Returns:
        Six (4, 3) arrays of corner coordinates [m] in the world frame.
    """
    h = 0.5 * np.asarray(size, dtype=float)
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
    corners = (pose[:3, :3] @ (signs * h).T).T + pose[:3, 3]
    quads = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
    return [corners[list(q)] for q in quads]


def cylinder_faces(radius: float, length: float, pose: np.ndarray, n: int = 24) -> list[np.ndarray]:
    """Faces of a cylinder whose axis is the local z axis (URDF convention).

    Args:
        radius: radius [m].
        length: length along the local z axis [m].
        pose: (4, 4) homogeneous transform of the cylinder centre in the world frame.
        n: number of facets around the axis.

    Returns:
        n side quads of shape (4, 3) and two end caps of shape (n, 3), world frame [m].
    """
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    ring = np.stack([radius * np.cos(t), radius * np.sin(t), np.zeros(n)], axis=1)
    lo = ring + np.array([0.0, 0.0, -0.5 * length])
    hi = ring + np.array([0.0, 0.0, 0.5 * length])
    rot, pos = pose[:3, :3], pose[:3, 3]
    lo_w = (rot @ lo.T).T + pos
    hi_w = (rot @ hi.T).T + pos
    sides = [np.array([lo_w[i], lo_w[(i + 1) % n], hi_w[(i + 1) % n], hi_w[i]]) for i in range(n)]
    return [*sides, lo_w, hi_w]


def _geometry_faces(geometry: Any, pose: np.ndarray) -> list[np.ndarray]:
    """Faces for a yourdfpy Geometry at a world pose; [] for meshes or unknown shapes."""
    if geometry.box is not None:
        return box_faces(np.asarray(geometry.box.size, dtype=float), pose)
    if geometry.cylinder is not None:
        cyl = geometry.cylinder
        return cylinder_faces(float(cyl.radius), float(cyl.length), pose)
    if geometry.sphere is not None:
        r = float(geometry.sphere.radius)
        return box_faces(np.array([2 * r, 2 * r, 2 * r]), pose)  # coarse stand-in
    return []


def _link_colour(link: Any, index: int) -> Any:
    """RGBA from the first visual material with a colour, else a palette entry."""
    for vis in link.visuals:
        mat = vis.material
        if mat is not None and mat.color is not None and mat.color.rgba is not None:
            return tuple(float(c) for c in mat.color.rgba)
    return _PALETTE[index % len(_PALETTE)]


def draw(model_path: Path, out_path: Path) -> int:
    """Render `model_path` at q = 0 to the PNG `out_path`.

    Args:
        model_path: URDF file.
        out_path: PNG to write (written atomically; must not be the model file).

    Returns:
        Number of links drawn.
    """
    import pinocchio as pin
    import yourdfpy
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    try:
        from bondid.atomic import write_bytes_atomic
    except ImportError:  # run from a checkout without PYTHONPATH=src
        sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))
        from bondid.atomic import write_bytes_atomic

    urdf = yourdfpy.URDF.load(str(model_path), build_scene_graph=False, load_meshes=False)
    model = pin.buildModelFromUrdf(str(model_path))
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))

    fig = Figure(figsize=(9, 7.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    points: list[np.ndarray] = []
    drawn = 0
    for index, link in enumerate(urdf.robot.links):
        shapes = link.collisions or link.visuals
        if not shapes or not model.existFrame(link.name):
            continue
        placement = data.oMf[model.getFrameId(link.name)]
        world = np.eye(4)
        world[:3, :3] = placement.rotation
        world[:3, 3] = placement.translation
        colour = _link_colour(link, index)
        link_points: list[np.ndarray] = []
        for shape in shapes:
            local = shape.origin if shape.origin is not None else np.eye(4)
            faces = _geometry_faces(shape.geometry, world @ local)
            if not faces:
                continue
            poly = Poly3DCollection(faces, facecolor=colour, edgecolor="k", linewidths=0.3)
            poly.set_alpha(0.35)
            ax.add_collection3d(poly)
            link_points.extend(faces)
        points.extend(link_points)
        origin = world[:3, 3]
        ax.scatter(*origin, color="k", marker="+", s=40)
        if link_points:
            cloud = np.vstack(link_points)
            label_at = np.array([cloud[:, 0].max(), cloud[:, 1].mean(), cloud[:, 2].max()])
        else:
            label_at = origin
        ax.text(
            *label_at,
            f" {link.name}",
            fontsize=9,
            weight="bold",
            zorder=10,
            bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "none", "pad": 1.0},
        )
        if link.inertial is not None and link.inertial.origin is not None:
            com = world[:3, :3] @ link.inertial.origin[:3, 3] + origin
            ax.scatter(*com, color="k", marker="o", s=12)
        drawn += 1

    if points:
        cloud = np.vstack(points)
        lo, hi = cloud.min(axis=0), cloud.max(axis=0)
        centre, half = 0.5 * (lo + hi), 0.5 * float(np.max(hi - lo))
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        ax.set_zlim(centre[2] - half, centre[2] + half)
        ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.view_init(elev=22, azim=-58)
    ax.set_title(f"{urdf.robot.name} at q = 0 (collision geometry; + frame, o CoM)")

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    write_bytes_atomic(out_path, buffer.getvalue())
    return drawn


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point; returns the exit code (0 ok, 2 bad input)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", required=True, type=Path, help="URDF file")
    parser.add_argument("--out", required=True, type=Path, help="PNG file to write")
    args = parser.parse_args(argv)
    if not args.model.is_file():
        print(f"error: {args.model}: no such URDF file", file=sys.stderr)
        return 2
    if args.out.resolve() == args.model.resolve():
        print(f"error: {args.out}: refusing to overwrite the input model", file=sys.stderr)
        return 2
    count = draw(args.model, args.out)
    print(f"drew {count} links of {args.model} -> {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Convex hull of a link's geometry, as linear inequalities ``A x ≤ b`` in the LINK frame.

Built from a yourdfpy link's collision elements (its visual elements when it has no collision
element). Boxes are exact; cylinders and spheres are replaced by an INSCRIBED polytope (every
vertex lies on the true surface, so the polytope lies inside the true shape: a CoM constraint
built from it is conservative); meshes are loaded with trimesh and scaled by ``mesh.scale``.
Several elements give the hull of all their points. yourdfpy's private ``_link_mesh()`` is not
used (it is broken in 0.0.60).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from bondid.exceptions import ComputationError, ModelError

FloatArray = NDArray[np.float64]

#: Default number of sides of the polygon inscribed in a cylinder's (or sphere's) circles.
DEFAULT_SIDES = 16


@dataclass(frozen=True, eq=False)
class Hull:
    """Convex polytope ``{x : A x ≤ b}`` (m, link frame).

    Attributes:
        A: (n_facets, 3) unit outward facet normals (coplanar facets merged).
        b: (n_facets,) offsets in m (signed distance of each facet plane from the origin).
        vertices: (n_vertices, 3) vertices in m.
    """

    A: FloatArray
    b: FloatArray
    vertices: FloatArray

    @cached_property
    def _triangles(self) -> FloatArray:
        """Boundary triangles (n, 3, 3) of the hull, for exact outside distances."""
        from scipy.spatial import ConvexHull

        return np.asarray(self.vertices[ConvexHull(self.vertices).simplices], dtype=float)

    @property
    def size(self) -> float:
        """Diagonal of the axis-aligned bounding box of the vertices (m)."""
        return float(np.linalg.norm(np.ptp(self.vertices, axis=0)))

    def contains(self, x: ArrayLike, margin: float = 0.0) -> Any:
        """Whether point(s) ``x`` ((3,) or (n, 3), m) satisfy ``A x ≤ b − margin``.

        Returns a bool for one point, a bool array (n,) for several. A negative margin
        tolerates points up to ``-margin`` outside a facet plane.
        """
        pts = np.asarray(x, dtype=float)
        inside = np.all(pts @ self.A.T <= self.b - margin, axis=-1)
        return bool(inside) if pts.ndim == 1 else inside

    def distance(self, x: ArrayLike) -> float:
        """Signed Euclidean distance (m) from point ``x`` (3,) to the boundary, positive inside."""
        p = np.asarray(x, dtype=float).reshape(3)
        slack = self.b - self.A @ p
        if np.all(slack >= 0.0):
            return float(np.min(slack))
        return -float(np.linalg.norm(p - self.nearest_point(p)))

    def nearest_point(self, x: ArrayLike) -> FloatArray:
        """Euclidean projection (3,) of point ``x`` (3,) onto the hull (``x`` itself if inside)."""
        import trimesh

        p = np.asarray(x, dtype=float).reshape(3)
        if self.contains(p):
            return p.copy()
        tri = self._triangles
        cand = trimesh.triangles.closest_point(tri, np.repeat(p[None, :], len(tri), axis=0))
        return np.asarray(cand[np.argmin(np.sum((cand - p) ** 2, axis=1))], dtype=float)

    def shrunk(self, margin: float) -> Hull:
        """The hull with every facet moved inwards by ``margin`` (m): ``A x ≤ b − margin``.

        Raises:
            ComputationError: if the shrunk polytope is empty (margin ≥ the inradius).
        """
        return hull_from_halfspaces(self.A, self.b - float(margin))


def _merge_facets(equations: FloatArray, tol: float) -> tuple[FloatArray, FloatArray]:
    """Unit-normalised ``(A, b)`` of qhull equations ``n·x + d ≤ 0``, duplicate planes merged."""
    normals = equations[:, :3]
    norms = np.linalg.norm(normals, axis=1)
    A = normals / norms[:, None]
    b = -equations[:, 3] / norms
    keep: list[int] = []
    for i in range(len(A)):
        if keep:
            k = np.asarray(keep)
            same = (A[k] @ A[i] > 1.0 - 1e-9) & (np.abs(b[k] - b[i]) <= tol)
            if np.any(same):
                continue
        keep.append(i)
    return A[keep], b[keep]


def hull_from_points(points: ArrayLike, name: str | None = None) -> Hull:
    """Convex hull of points (n, 3) in m.

    Raises:
        ModelError: if the points span less than three dimensions (flat or empty geometry).
    """
    from scipy.spatial import ConvexHull, QhullError

    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    label = f"link {name!r}" if name else "geometry"
    try:
        qh = ConvexHull(pts)
    except (QhullError, ValueError) as exc:
        raise ModelError(
            f"{label}: geometry is empty or flat ({len(pts)} points); a hull needs a 3-D body"
        ) from exc
    vertices = pts[qh.vertices]
    scale = max(float(np.linalg.norm(np.ptp(vertices, axis=0))), 1e-300)
    A, b = _merge_facets(qh.equations, 1e-9 * scale)
    return Hull(A=A, b=b, vertices=vertices)


def hull_from_halfspaces(A: ArrayLike, b: ArrayLike) -> Hull:
    """Bounded polytope ``{x : A x ≤ b}`` (A (n, 3), b (n,) m) as a :class:`Hull`.

    Raises:
        ComputationError: if the polytope is empty, flat or unbounded.
    """
    from scipy.optimize import linprog
    from scipy.spatial import HalfspaceIntersection, QhullError

    Am = np.asarray(A, dtype=float).reshape(-1, 3)
    bm = np.asarray(b, dtype=float).reshape(-1)
    norms = np.linalg.norm(Am, axis=1)
    Am, bm = Am / norms[:, None], bm / norms
    # Chebyshev centre: maximise r subject to A x + r ≤ b.
    res = linprog(
        c=[0.0, 0.0, 0.0, -1.0],
        A_ub=np.hstack([Am, np.ones((len(Am), 1))]),
        b_ub=bm,
        bounds=[(None, None)] * 3 + [(0.0, None)],
        method="highs",
    )
    if res.status != 0 or res.x[3] <= 0.0:
        raise ComputationError(
            f"polytope with {len(Am)} facets is empty, flat or unbounded (Chebyshev radius "
            f"{res.x[3] if res.x is not None else float('nan'):.3g} m); use a smaller margin"
        )
    try:
        hs = HalfspaceIntersection(np.hstack([Am, -bm[:, None]]), res.x[:3])
    except QhullError as exc:
        raise ComputationError(f"halfspace intersection of {len(Am)} facets failed") from exc
    return hull_from_points(hs.intersections)


def _element_points(
    geometry: Any, resolve: Callable[[str], str] | None, n_sides: int, label: str
) -> FloatArray | None:
    """Points (n, 3) in the element frame spanning one yourdfpy Geometry (None if empty)."""
    if geometry is None:
        return None
    if geometry.box is not None:
        half = 0.5 * np.asarray(geometry.box.size, dtype=float).reshape(3)
        signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
        return signs * half
    if geometry.cylinder is not None:
        r, length = float(geometry.cylinder.radius), float(geometry.cylinder.length)
        ang = 2.0 * np.pi * np.arange(n_sides) / n_sides
        ring = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
        return np.vstack(
            [np.column_stack([ring, np.full(n_sides, z)]) for z in (-0.5 * length, 0.5 * length)]
        )
    if geometry.sphere is not None:
        r = float(geometry.sphere.radius)
        n_lat = max(n_sides // 2, 2)
        pol = np.pi * np.arange(1, n_lat) / n_lat
        azi = 2.0 * np.pi * np.arange(n_sides) / n_sides
        P, Z = np.meshgrid(pol, azi, indexing="ij")
        rings = np.column_stack(
            [(np.sin(P) * np.cos(Z)).ravel(), (np.sin(P) * np.sin(Z)).ravel(), np.cos(P).ravel()]
        )
        return r * np.vstack([rings, [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]])
    if geometry.mesh is not None:
        return _mesh_points(geometry.mesh, resolve, label)
    return None


@lru_cache(maxsize=64)
def _mesh_vertices(path: str, _mtime_ns: int, _size: int) -> FloatArray:
    """The vertices of the mesh file ``path`` (read-only; cached per file version: a
    diagnosis asks for the hull of one link once per candidate)."""
    import trimesh

    loaded: Any = trimesh.load(path, force="mesh")
    out = np.asarray(loaded.vertices, dtype=np.float64).reshape(-1, 3).copy()
    out.setflags(write=False)
    return out


def _mesh_points(mesh: Any, resolve: Callable[[str], str] | None, label: str) -> FloatArray:
    filename = str(mesh.filename)
    if resolve is None:
        raise ModelError(f"{label}: mesh {filename!r} needs a resolve(filename) -> path callable")
    path = resolve(filename)
    if not os.path.isfile(path):
        raise ModelError(f"{label}: mesh {filename!r} resolved to {path!r}, which is not a file")
    st = os.stat(path)
    try:
        vertices: FloatArray = _mesh_vertices(os.path.abspath(path), st.st_mtime_ns, st.st_size)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise ModelError(f"{label}: cannot read mesh {path!r}: {exc}") from exc
    if mesh.scale is not None:
        vertices = vertices * np.broadcast_to(np.asarray(mesh.scale, dtype=np.float64), (3,))
    return vertices


def link_hull(
    link_geometries: Any,
    resolve: Callable[[str], str] | None = None,
    *,
    n_sides: int = DEFAULT_SIDES,
    name: str | None = None,
) -> Hull | None:
    """Convex hull (link frame, m) of a link's geometry, or None if it has none.

    Args:
        link_geometries: a yourdfpy ``Link`` (its ``collisions``, else its ``visuals`` are used)
            or an iterable of yourdfpy ``Collision``/``Visual`` elements (each with ``.origin``
            (4, 4) or None and ``.geometry``).
        resolve: maps a mesh filename as written in the URDF (``package://…``, relative, …) to a
            file path; needed only when a mesh is present. See :func:`make_resolver`.
        n_sides: sides of the polygons inscribed in cylinder and sphere circles (≥ 3).
        name: link name for messages (defaults to the Link's name).

    Returns:
        :class:`Hull`, or None when there is no geometry (the caller decides what that means).

    Raises:
        ModelError: unreadable mesh, missing ``resolve``, flat geometry, ``n_sides < 3``.
    """
    if hasattr(link_geometries, "collisions"):
        name = name or getattr(link_geometries, "name", None)
        elements: Iterable[Any] = link_geometries.collisions or link_geometries.visuals or []
    else:
        elements = link_geometries
    label = f"link {name!r}" if name else "link"
    if n_sides < 3:
        raise ModelError(f"{label}: n_sides must be >= 3, got {n_sides}")
    clouds = []
    for element in elements:
        pts = _element_points(getattr(element, "geometry", None), resolve, n_sides, label)
        if pts is None or len(pts) == 0:
            continue
        origin = getattr(element, "origin", None)
        if origin is not None:
            T = np.asarray(origin, dtype=float).reshape(4, 4)
            pts = pts @ T[:3, :3].T + T[:3, 3]
        clouds.append(pts)
    if not clouds:
        return None
    return hull_from_points(np.vstack(clouds), name)


def make_resolver(
    urdf_dir: str | os.PathLike[str], package_dirs: Mapping[str, str | os.PathLike[str]]
) -> Callable[[str], str]:
    """A ``resolve(filename) -> path`` for :func:`link_hull`.

    ``package://<pkg>/<rest>`` → ``package_dirs[<pkg>]/<rest>``; ``file://<path>`` → ``<path>``;
    a relative path is taken relative to ``urdf_dir``.
    """

    def resolve(filename: str) -> str:
        if filename.startswith("package://"):
            pkg, _, rest = filename[len("package://") :].partition("/")
            if pkg not in package_dirs:
                raise ModelError(
                    f"mesh {filename!r}: unknown package {pkg!r}; known: {sorted(package_dirs)}"
                )
            return os.path.join(os.fspath(package_dirs[pkg]), rest)
        if filename.startswith("file://"):
            return filename[len("file://") :]
        return os.path.join(os.fspath(urdf_dir), filename)

    return resolve

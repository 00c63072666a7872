"""Synthetic CAD-like training shapes: flat faces meeting at sharp edges, the kind of
surface the shared scans lack (only one of the shared meshes, the fandisk, is CAD, and it
is kept for evaluation).

Each shape is a surface of revolution of a polyline profile (r, z) or a subdivided box,
with the profile resampled so that triangles are close to equilateral, scaled to a unit
bounding-box diagonal.  ``shape(name)`` builds one; ``SHAPES`` names them.
"""

from __future__ import annotations

import numpy as np
import trimesh

import jaxmesh

#: profiles (r, z) from the axis back to the axis: a stepped shaft, a flanged ring, a cone
#: frustum on a disc, a hexagonal nut (6 sections)
PROFILES = {
    "shaft": ([(0, 0), (0.5, 0), (0.5, 0.6), (0.3, 0.6), (0.3, 1.2), (0.4, 1.2), (0.4, 1.5), (0, 1.5)], 64),
    "flange": ([(0, 0), (0.9, 0), (0.9, 0.2), (0.45, 0.2), (0.45, 0.9), (0, 0.9)], 72),
    "frustum": ([(0, 0), (0.8, 0), (0.8, 0.25), (0.35, 0.9), (0, 0.9)], 64),
    "nut": ([(0, 0), (0.7, 0), (0.7, 0.5), (0.25, 0.5), (0.25, 0.35), (0, 0.35)], 6),
}
SHAPES = ("box", *PROFILES)


def _resample(points: list, step: float) -> np.ndarray:
    out = [np.asarray(points[0], float)]
    for a, b in zip(points[:-1], points[1:]):
        a, b = np.asarray(a, float), np.asarray(b, float)
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out += [a + (b - a) * t for t in np.linspace(0, 1, n + 1)[1:]]
    return np.asarray(out)


def _revolved(profile: list, sections: int, target_edge: float) -> trimesh.Trimesh:
    r_max = max(p[0] for p in profile)
    step = 2 * target_edge if sections <= 8 else min(target_edge, 2 * np.pi * r_max / sections)
    line = _resample(profile, step)
    mesh = trimesh.creation.revolve(line, sections=sections)
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    # a few sections leave wide flat facets: split them to the target edge (the profile then
    # needs no resampling finer than twice the target)
    return mesh.subdivide_to_size(2 * target_edge) if sections <= 8 else mesh


def shape(name: str, target_edge: float = 0.05) -> jaxmesh.Mesh:
    """The synthetic shape ``name`` (one of :data:`SHAPES`), float64, unit diagonal."""
    if name == "box":
        mesh = trimesh.creation.box((1.0, 0.7, 0.4)).subdivide_to_size(target_edge)
    elif name in PROFILES:
        mesh = _revolved(*PROFILES[name], target_edge)
    else:
        raise SystemExit(f"unknown shape {name!r}; known: {', '.join(SHAPES)}")
    mesh.merge_vertices()
    v, f = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
    return jaxmesh.normalize(jaxmesh.Mesh.from_arrays(v, f, dtype=np.float64))

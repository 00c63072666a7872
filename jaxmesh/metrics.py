"""Error metrics between a reference mesh and an estimate.

Vertex-correspondence metrics (same connectivity; ``estimate`` may be a Mesh or
a vertex array of shape (*batch, V, 3)) are pure JAX, jittable and
differentiable: :func:`visual_error` (thesis ch.2 eq.13),
:func:`nonlinear_visual_error` (ch.3 eq.6–10), :func:`rms_vertex_error`,
:func:`mean_normal_angle_error`.  :func:`surface_distance` needs no
correspondence (different connectivity, reordered vertices) and runs on the host.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .geometry import face_normals
from .mesh import Mesh, as_device_array
from .operators import gradient_magnitude, umbrella
from ._private import lift, safe_divide, safe_norm, segment_sum_rows

__all__ = [
    "visual_error",
    "nonlinear_visual_error",
    "nonlinear_diffusion_operator",
    "cauchy_weight",
    "rms_vertex_error",
    "mean_normal_angle_error",
    "error_summary",
    "surface_distance",
    "point_triangle_distance",
    "sample_surface",
]

CAUCHY_C = 2.3849


def _positions(reference: Mesh, estimate) -> Float[Array, "*batch V 3"]:
    x = estimate.vertices if isinstance(estimate, Mesh) else as_device_array(estimate)
    if x.shape[-2:] != (reference.num_vertices, 3):
        raise ValueError(
            f"estimate must have {reference.num_vertices} vertices (same connectivity as "
            f"the reference), got shape {x.shape}; use surface_distance for meshes without "
            "vertex correspondence"
        )
    return x


def visual_error(reference: Mesh, estimate) -> Float[Array, "*batch"]:
    """E = (1/2m) ( sum_i ||v_i - v̂_i||^2 + sum_i ||GL(v_i) - GL(v̂_i)||^2 ),
    GL(v_i) = v_i - (1/d_i) sum_{j ~ i} v_j   (thesis ch.2 eq.13, Karni & Gotsman).

    Both terms use the reference's connectivity.  Units: length squared.

    Arguments:
        reference: the reference mesh; its connectivity is used.
        estimate: a mesh with the reference's connectivity, or its vertices (*batch, V, 3).

    Returns:
        One value per mesh, (*batch)."""
    return _visual_error(reference, _positions(reference, estimate))


# The metrics' bodies are jitted: an eager call compiles one program per shape instead
# of one per primitive (under an outer jit they are inlined as usual).
@jax.jit
def _visual_error(reference: Mesh, x):
    v = lift(reference.vertices, x.ndim)
    diff = v - x
    gl = umbrella(reference, diff)  # GL is linear: GL(v) - GL(x) = -K(v - x)
    m = reference.num_vertices
    return (jnp.sum(diff * diff, axis=(-2, -1)) + jnp.sum(gl * gl, axis=(-2, -1))) / (2 * m)


def cauchy_weight(x: Array, c: float | Array = CAUCHY_C) -> Array:
    """g(x) = 1 / (1 + x^2 / c^2)   (thesis ch.3 eq.10).

    Arguments:
        x: the values (any shape).
        c: the constant c (a number, or an array broadcasting with x).

    Returns:
        g(x), the shape of x."""
    return 1 / (1 + (x / c) ** 2)


def nonlinear_diffusion_operator(
    mesh: Mesh, x: Float[Array, "*batch V 3"], c: float = CAUCHY_C, variant: str = "paper"
) -> Float[Array, "*batch V 3"]:
    """𝒜(v_i) = (1/d_i) sum_{j ~ i} (v_i - v_j)(g(|∇v_i|) + g(|∇v_j|))  (thesis ch.3 eq.7),
    |∇v_i| from :func:`jaxmesh.operators.gradient_magnitude` with ``variant``.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: positions, (*batch, V, 3).
        c: the Cauchy constant, an absolute length (thesis: 2.3849).
        variant: ``"paper"`` or ``"translation_invariant"`` gradient magnitudes.

    Returns:
        (*batch, V, 3) array."""
    g = cauchy_weight(gradient_magnitude(mesh, x, variant), c)
    phi = (g[..., mesh.src] + g[..., mesh.dst])[..., None]
    terms = phi * (x[..., mesh.src, :] - x[..., mesh.dst, :])
    d = lift(mesh.degree.astype(x.dtype)[:, None], x.ndim)
    return safe_divide(segment_sum_rows(terms, mesh.src, mesh.num_vertices), d)


def nonlinear_visual_error(
    reference: Mesh, estimate, c: float = CAUCHY_C, variant: str = "paper"
) -> Float[Array, "*batch"]:
    """D = (1/2m) sum ||v_i - v̂_i||^2 + (1/2m) sum ||𝒜(v_i) - 𝒜(v̂_i)||^2
    (thesis ch.3 eq.6), 𝒜 the nonlinear diffusion operator (eq.7–10), each
    model's operator evaluated on its own positions, c = 2.3849.

    ``variant="paper"``: the gradient magnitude of eq.8 with its 1/sqrt(d)
    normalisation, which makes D change when both meshes are translated
    together wherever neighbouring degrees differ (a defect of the formula).
    ``variant="translation_invariant"`` uses sqrt(sum_j ||v_i - v_j||^2) instead.
    Note that c is an absolute length: D depends on the mesh's units.

    Arguments:
        reference: the reference mesh; its connectivity is used.
        estimate: a mesh with the reference's connectivity, or its vertices (*batch, V, 3).
        c: the Cauchy constant, an absolute length (thesis: 2.3849).
        variant: ``"paper"`` (eq.8's gradient) or ``"translation_invariant"``.

    Returns:
        One value per mesh, (*batch)."""
    return _nonlinear_visual_error(reference, _positions(reference, estimate), c, variant)


@functools.partial(jax.jit, static_argnames=("c", "variant"))
def _nonlinear_visual_error(reference: Mesh, x, c: float, variant: str):
    v = lift(reference.vertices, x.ndim)
    diff = v - x
    a_ref = nonlinear_diffusion_operator(reference, v, c, variant)
    a_est = nonlinear_diffusion_operator(reference, x, c, variant)
    da = a_ref - a_est
    m = reference.num_vertices
    return (jnp.sum(diff * diff, axis=(-2, -1)) + jnp.sum(da * da, axis=(-2, -1))) / (2 * m)


def rms_vertex_error(reference: Mesh, estimate) -> Float[Array, "*batch"]:
    """sqrt( (1/m) sum_i ||v_i - v̂_i||^2 ).

    Arguments:
        reference: the reference mesh; its connectivity is used.
        estimate: a mesh with the reference's connectivity, or its vertices (*batch, V, 3).

    Returns:
        One value per mesh, (*batch)."""
    return _rms_vertex_error(reference, _positions(reference, estimate))


@jax.jit
def _rms_vertex_error(reference: Mesh, x):
    diff = lift(reference.vertices, x.ndim) - x
    return jnp.sqrt(jnp.mean(jnp.sum(diff * diff, axis=-1), axis=-1))


def mean_normal_angle_error(reference: Mesh, estimate) -> Float[Array, "*batch"]:
    """Mean over faces of the angle, in degrees, between the reference's and the
    estimate's unit face normals: atan2(||n x n̂||, n . n̂).  Faces that are
    degenerate in either mesh (zero normal) are left out of the mean.

    Arguments:
        reference: the reference mesh; its connectivity is used.
        estimate: a mesh with the reference's connectivity, or its vertices (*batch, V, 3).

    Returns:
        One value per mesh, (*batch)."""
    return _mean_normal_angle_error(reference, _positions(reference, estimate))


@jax.jit
def _mean_normal_angle_error(reference: Mesh, x):
    n_ref = lift(face_normals(reference), x.ndim)
    n_est = face_normals(reference.with_vertices(x))
    ang = jnp.arctan2(safe_norm(jnp.cross(n_ref, n_est)), jnp.sum(n_ref * n_est, axis=-1))
    valid = (jnp.sum(n_ref * n_ref, axis=-1) > 0) & (jnp.sum(n_est * n_est, axis=-1) > 0)
    total = jnp.sum(jnp.where(valid, ang, 0), axis=-1)
    count = jnp.sum(valid, axis=-1).astype(ang.dtype)
    return jnp.degrees(safe_divide(total, count))


def error_summary(reference: Mesh, estimate: Mesh) -> dict[str, float]:
    """The two errors jaxmesh reports against a clean mesh, as Python floats:
    ``visual_error`` (:func:`visual_error`, E) and ``normal_angle_deg``
    (:func:`mean_normal_angle_error`).  Host-side (concrete values); the CLI's and
    the dataset runner's reports.

    Arguments:
        reference: the clean mesh; its connectivity is used.
        estimate: a single mesh with the reference's connectivity.

    Returns:
        ``{"visual_error": E, "normal_angle_deg": degrees}``."""
    return {"visual_error": float(visual_error(reference, estimate)),
            "normal_angle_deg": float(mean_normal_angle_error(reference, estimate))}


# --------------------------------------------------------------------------
# correspondence-free distance (host side, numpy / scipy)


def point_triangle_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Exact Euclidean distance from points p (N, 3) to triangles (a, b, c) (N, 3 each).

    If the orthogonal projection of p onto the triangle's plane falls inside the
    triangle (barycentric u, v, w >= 0) the distance is the distance to the
    plane; otherwise the closest point lies on the boundary and the distance is
    the least of the three point–segment distances.  Degenerate triangles
    (zero area) fall through to the segment case.

    Arguments:
        p: points, (N, 3).
        a: first corners of the triangles, (N, 3).
        b: second corners, (N, 3).
        c: third corners, (N, 3).

    Returns:
        The distance of each point to its triangle, (N,)."""
    p, a, b, c = (np.asarray(t, dtype=np.float64) for t in (p, a, b, c))
    ab, ac, ap = b - a, c - a, p - a
    d00, d01, d11 = (ab * ab).sum(1), (ab * ac).sum(1), (ac * ac).sum(1)
    d20, d21 = (ap * ab).sum(1), (ap * ac).sum(1)
    denom = d00 * d11 - d01 * d01
    ok = denom > np.finfo(np.float64).eps * np.maximum(d00 * d11, np.finfo(np.float64).tiny)
    safe = np.where(ok, denom, 1.0)
    v = (d11 * d20 - d01 * d21) / safe
    w = (d00 * d21 - d01 * d20) / safe
    inside = ok & (v >= 0) & (w >= 0) & (v + w <= 1)
    proj = a + v[:, None] * ab + w[:, None] * ac
    best = np.where(inside, ((p - proj) ** 2).sum(1), np.inf)

    def seg_sq(u, s):
        d = s - u
        dd = (d * d).sum(1)
        t = np.clip(((p - u) * d).sum(1) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
        q = u + t[:, None] * d
        return ((p - q) ** 2).sum(1)

    out = ~inside
    if out.any():
        edge = np.minimum(np.minimum(seg_sq(a, b), seg_sq(a, c)), seg_sq(b, c))
        best = np.where(out, edge, best)
    return np.sqrt(best)


def _point_surface_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Exact distance from each point to the triangle surface (vertices, faces)."""
    from scipy.spatial import cKDTree

    tri = vertices[faces]  # (F, 3, 3)
    centroid = tri.mean(axis=1)
    radius = np.sqrt(((tri - centroid[:, None, :]) ** 2).sum(-1)).max(axis=1)
    upper, _ = cKDTree(vertices).query(points)  # a vertex is on the surface
    tree = cKDTree(centroid)
    r_max = radius.max()
    out = np.empty(len(points))
    chunk = 4096
    for s in range(0, len(points), chunk):
        pts, ub = points[s:s + chunk], upper[s:s + chunk]
        cand = tree.query_ball_point(pts, ub + r_max)
        lens = np.fromiter((len(cx) for cx in cand), dtype=np.int64, count=len(cand))
        qi = np.repeat(np.arange(len(pts)), lens)
        ti = np.fromiter((t for cx in cand for t in cx), dtype=np.int64, count=int(lens.sum()))
        # a triangle can only matter if its bounding sphere reaches within the bound
        keep = np.sqrt(((pts[qi] - centroid[ti]) ** 2).sum(1)) - radius[ti] <= ub[qi]
        qi, ti = qi[keep], ti[keep]
        d = point_triangle_distance(pts[qi], tri[ti, 0], tri[ti, 1], tri[ti, 2])
        best = ub.copy()
        np.minimum.at(best, qi, d)
        out[s:s + chunk] = best
    return out


def sample_surface(vertices: np.ndarray, faces: np.ndarray, count: int, rng: np.random.Generator, *,
                   systematic: bool = False, area: np.ndarray | None = None) -> np.ndarray:
    """``count`` points distributed uniformly on the surface: faces drawn with
    probability ∝ area, then a uniform point in each, v = (1 − √r₁) a + √r₁ (1 − r₂) b
    + √r₁ r₂ c.  Faces are drawn independently, or, with ``systematic``, by
    systematic sampling of the area CDF (one uniform offset; lower variance: what
    the robust hash uses).  ``area``: face weights to use instead of the faces'
    areas (the robust hash samples its normalised surface with the original
    areas).

    Arguments:
        vertices: the surface's vertices, (V, 3).
        faces: its triangles, (F, 3).
        count: the number of points.
        rng: the numpy generator to draw from.
        systematic: systematic sampling of the area CDF instead of independent draws.
        area: face weights to use instead of the faces' areas.

    Returns:
        The points, (count, 3)."""
    tri = vertices[faces]
    if area is None:
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if area.sum() <= 0:
        return tri[:, 0][rng.integers(0, len(faces), count)]
    if systematic:
        cdf = np.cumsum(area) / area.sum()
        f = np.minimum(np.searchsorted(cdf, (np.arange(count) + rng.random()) / count), len(faces) - 1)
    else:
        f = rng.choice(len(faces), size=count, p=area / area.sum())
    r1, r2 = rng.random(count), rng.random(count)
    s = np.sqrt(r1)
    w = np.stack([1 - s, s * (1 - r2), s * r2], axis=1)
    return np.einsum("nk,nkd->nd", w, tri[f])


def surface_distance(a, b, samples: int = 20000, seed: int = 0) -> dict[str, float]:
    """Symmetric, correspondence-free distance between two triangle surfaces.

    Draws ``samples`` area-uniform points on each surface (fixed ``seed``) and
    measures the exact point-to-surface distance to the other one (k-d tree
    bound plus exact point–triangle distances).  Returns

    * ``rms``: sqrt of the mean squared distance over both directions' samples;
    * ``mean``: mean distance over both directions;
    * ``hausdorff``: the largest distance over the samples *and all vertices*
      of both meshes (a lower bound of the true Hausdorff distance that tightens
      with ``samples``);
    * ``diagonal``: the bounding-box diagonal of ``a``, for relative errors.

    ``a`` and ``b`` are :class:`Mesh` objects or ``(vertices, faces)`` pairs.

    Arguments:
        a: the first surface (its bounding-box diagonal is reported).
        b: the second surface.
        samples: points drawn on each surface.
        seed: the sampling seed.

    Returns:
        A dict with ``rms``, ``mean``, ``hausdorff`` and ``diagonal`` (see above)."""
    def arrays(m):
        if isinstance(m, Mesh):
            if m.batch_shape:
                raise ValueError("surface_distance needs single meshes")
            return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)
        v, f = m
        return np.asarray(v, np.float64), np.asarray(f, np.int64)

    va, fa = arrays(a)
    vb, fb = arrays(b)
    rng = np.random.default_rng(seed)
    pa = sample_surface(va, fa, samples, rng)
    pb = sample_surface(vb, fb, samples, rng)
    d_ab = _point_surface_distance(pa, vb, fb)
    d_ba = _point_surface_distance(pb, va, fa)
    h_vert = max(_point_surface_distance(va, vb, fb).max(), _point_surface_distance(vb, va, fa).max())
    both = np.concatenate([d_ab, d_ba])
    return {
        "rms": float(np.sqrt(np.mean(both ** 2))),
        "mean": float(both.mean()),
        "hausdorff": float(max(both.max(), h_vert)),
        "diagonal": float(np.linalg.norm(va.max(0) - va.min(0))),
    }

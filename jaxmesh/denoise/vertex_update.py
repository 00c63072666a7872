"""The vertex update shared by every two-step (normal-filtering) denoiser.

Given target unit face normals n_f (the filtered normals), the vertices are
moved so that every edge of every face becomes orthogonal to its target
normal, i.e. towards a minimum of

    Σ_f Σ_{(i,j) ∈ ∂f} (n_f · (x_j − x_i))²,

by the iteration of Sun, Rosin, Martin & Langbein 2007 (their eq. 11):

    x_i ← x_i + (1 / |F_i|) Σ_{f ∈ F_i} n_f (n_f · (c_f − x_i)),

F_i the faces around vertex i, c_f the centroid of f at the current
positions.  A vertex moves only along the target normals of its own faces, so
tangential positions are kept; a target normal and its negative give the same
step (n nᵀ is even in n), so the update cannot be misled by the sign of a
filtered normal.  Optional per-face ``weights`` w_f replace 1/|F_i| by
w_f / Σ_{f∈F_i} w_f (Yagou et al. 2002 use the face areas).

**Tangential relaxation** (``tangential`` = t > 0, not in Sun et al.).  The
update moves vertices along normals only, so under isotropic noise the
tangential half of the noise stays and thin, folded triangles remain, whose
normals no filter can fix.  After each step, every vertex also moves by
t · P_i (K x)_i, K the umbrella operator and P_i = I − m_i m_iᵀ the projection
onto the plane of m_i = normalize(Σ_{f∋i} n_f): the mesh is evened out within
the surface, which keeps its shape to first order.  Measured on the unit
fandisk at 0.3ℓ̄ (guided filtering, defaults): isotropic noise 15.1° → 4.8°
mean normal error with t = 0.1; noise along the normals 2.91° → 2.97°.

Given the face graph (:func:`~jaxmesh.denoise.face_graph`), the sums over F_i and
the umbrella run along its padded vertex tables, one slot at a time (faster on
CPU than the segment sums over the face corners used without it; the same sums
up to their order: ``benchmarks/bench_ring_sums.py``).
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from .._private import dot, lift, safe_divide, safe_normalize, segment_sum_rows, segment_sum_scalars, slot_sum
from ..mesh import Mesh
from ..operators import umbrella
from ._loop import iterate
from .face_graph import FaceGraph
from .vertex_rings import ring_umbrella

__all__ = ["vertex_update"]


def _corner_sums(corners: Int[Array, "V C"] | None, values: Float[Array, "*batch N d"],
                 num_vertices: int, faces) -> Float[Array, "*batch V d"]:
    """Σ over each vertex's corners of the per-corner ``values`` (N = 3F, corner 3f + k): along the
    padded table ``corners`` (padding 3F: a zero row), or as a segment sum over ``faces`` without it."""
    if corners is None:
        return segment_sum_rows(values, faces.reshape(-1), num_vertices)
    padded = jnp.concatenate([values, jnp.zeros_like(values[..., :1, :])], axis=-2)
    init = jnp.zeros((*values.shape[:-2], num_vertices, values.shape[-1]), values.dtype)
    return slot_sum(lambda slot: padded[..., slot, :], corners.T, init)


def vertex_update(
    mesh: Mesh, x: Float[Array, "*batch V 3"], normals: Float[Array, "*batch F 3"], iterations: int,
    weights: Float[Array, "*batch F"] | None = None, tangential=0.0, graph: FaceGraph | None = None,
) -> Float[Array, "*batch V 3"]:
    """``iterations`` steps of x_i ← x_i + Σ_{f∋i} w_f n_f (n_f·(c_f − x_i)) / Σ_{f∋i} w_f
    (module docstring; uniform w_f = 1 is Sun et al.'s update), each followed by
    the tangential relaxation x ← x + t P (K x) when ``tangential`` = t is not 0.
    Isolated vertices do not move.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        x: positions, (*batch, V, 3).
        normals: the target face normals, (*batch, F, 3).
        iterations: the number of steps.
        weights: per-face weights w_f, (*batch, F) (default: uniform).
        tangential: the tangential relaxation t per vertex-update step (0 = none).
        graph: the face graph (None: segment sums; module docstring).

    Returns:
        The updated positions, (*batch, V, 3)."""
    corners = mesh.faces.reshape(-1)
    table = None if graph is None else graph.vertex_corners
    w = jnp.ones(normals.shape[:-1], x.dtype) if weights is None else weights
    total = segment_sum_scalars(jnp.repeat(w, 3, axis=-1), corners, mesh.num_vertices)
    m = safe_normalize(_corner_sums(table, jnp.repeat(normals, 3, axis=-2), mesh.num_vertices, mesh.faces))
    t = lift(jnp.asarray(tangential, x.dtype)[..., None, None], x.ndim)

    def relax(y):
        k = umbrella(mesh, y) if graph is None else ring_umbrella(graph.vertex_rings, y)
        return y + t * (k - dot(k, m)[..., None] * m)

    def step(x):
        c = jnp.mean(x[..., mesh.faces, :], axis=-2)                            # (*b, F, 3)
        offset = c[..., :, None, :] - x[..., mesh.faces, :]                     # (*b, F, 3, 3)
        proj = dot(offset, normals[..., :, None, :])                             # (*b, F, 3)
        move = (w[..., :, None] * proj)[..., None] * normals[..., :, None, :]   # (*b, F, 3, 3)
        flat = move.reshape(*move.shape[:-3], -1, 3)
        y = x + safe_divide(_corner_sums(table, flat, mesh.num_vertices, mesh.faces), total[..., None])
        return y if isinstance(tangential, (int, float)) and tangential == 0 else relax(y)

    return iterate(step, x, iterations)

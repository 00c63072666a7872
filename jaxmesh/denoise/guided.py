"""Guided mesh normal filtering (Zhang, Deng, Zhang, Bouaziz & Liu 2015),
followed by the shared vertex update.

The bilateral normal filter (:mod:`.bilateral_normal`) compares the noisy
normals themselves in its range kernel, so noise decides which neighbours
count.  Guided filtering compares *guidance normals* instead, each the mean
normal of the most consistent patch near the face:

* the candidate patches of face f are P_j = N(j) for j ∈ N(f) (N the vertex
  ring, :mod:`.face_graph`);
* a patch's inconsistency is H(P) = D(P) · R(P), with
  D(P) = max_{a,b∈P} ‖n_a − n_b‖, the largest normal difference in the patch, and
  R(P) = max_{e∈E_P} φ_e / (ε + Σ_{e∈E_P} φ_e), the "relative total variation",
  φ_e = ‖n_a − n_b‖ across an interior edge e of P (E_P its interior edges,
  ε = 1e-9).  A patch on one side of a sharp edge has a small D; a noisy flat
  patch spreads its variation over many edges (small R); a patch across a
  feature has both large;
* the guidance normal of f is g_f = normalize(Σ_{a∈P*} A_a n_a) for the patch P*
  of least H among f's candidates.

One normal pass is then the joint bilateral filter
n_f ← normalize(Σ_{g∈N(f)} A_g W_s(f, g) W_r(‖g_f − g_g‖) n_g) with the same
kernels as bilateral normal filtering; the guidance is recomputed from the
current normals before every pass.  ``normal_iterations`` passes, then
``vertex_iterations`` vertex updates (with tangential relaxation ``tangential``,
:mod:`.vertex_update`), make one of ``iterations`` rounds.

Differentiability: the patch choice is piecewise constant (an argmin; it is
computed under ``stop_gradient``), so gradients with respect to the positions
and to ``sigma_s``, ``sigma_r`` hold the chosen patches fixed — exact almost
everywhere, as for the angle median.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._private import Scalar, one_program, safe_normalize, slot_sum
from ..mesh import Mesh
from .bilateral_normal import joint_bilateral_denoising
from .face_graph import FaceGraph, RingTier

__all__ = ["guided_normal_filtering", "patch_inconsistency", "guidance_normals"]

_EPS = 1e-9


#: a tier's rows (faces × batch) up to which its normal differences are formed in one pass; a larger
#: tier goes in blocks of ``_BLOCK_ROWS`` faces (one loop): past about 16k rows the one-pass program
#: ran several times slower per face on CPU (the bunny's 53k-face tier: 37 ms one pass, 10 ms in
#: blocks, 24 ms by the pairs a ≤ b gathered out of the ring)
_ONE_PASS_ROWS, _BLOCK_ROWS = 16384, 8192


def _ring_spread(normals: Float[Array, "*batch F 3"], ring: Int[Array, "W k"],
                 ring_mask: Bool[Array, "W k"]) -> Float[Array, "*batch W"]:
    """max_{a,b} ‖n_a − n_b‖² = max (2 − 2 n_a · n_b) over the pairs of each row's ring: every
    product n_a · n_b (k × k per face, written out by component) in one fused loop, no pair
    list gathered (2-4x faster on CPU than the k(k+1)/2 pairs a ≤ b gathered from the ring, and
    a batched (k, 3) @ (3, k) matmul per face is slower still)."""
    r = normals[..., ring, :]                                              # (*b, W, k, 3)
    dots = sum(r[..., :, None, c] * r[..., None, :, c] for c in range(3))  # (*b, W, k, k)
    pair = ring_mask[:, :, None] & ring_mask[:, None, :]
    return jnp.max(jnp.where(pair, 2 - 2 * dots, 0), axis=(-2, -1))


def _largest_difference(normals: Float[Array, "*batch F 3"], tier: RingTier) -> Float[Array, "*batch W"]:
    """max_{a,b∈N(f)} ‖n_a − n_b‖² for the faces f of one ring tier (:class:`~.face_graph.RingTier`):
    :func:`_ring_spread` in one pass, or a block of faces at a time for a large tier (padding rows
    are masked out and cut off)."""
    w, k = tier.ring.shape
    batch = int(np.prod(normals.shape[:-2], dtype=np.int64))
    if w * batch <= _ONE_PASS_ROWS:
        return _ring_spread(normals, tier.ring, tier.ring_mask)
    block = max(_BLOCK_ROWS // batch, 1)
    pad = -w % block
    ring = jnp.concatenate([tier.ring, jnp.zeros((pad, k), tier.ring.dtype)]).reshape(-1, block, k)
    mask = jnp.concatenate([tier.ring_mask, jnp.zeros((pad, k), bool)]).reshape(-1, block, k)
    out = jax.lax.map(lambda rm: _ring_spread(normals, *rm), (ring, mask))     # (blocks, *b, block)
    return jnp.moveaxis(out, 0, -2).reshape(*normals.shape[:-2], -1)[..., :w]


@one_program
def patch_inconsistency(graph: FaceGraph, normals: Float[Array, "*batch F 3"]) -> Float[Array, "*batch F"]:
    """H(P_j) = D(P_j) · R(P_j) for the patch P_j = N(j) of every face j (module docstring).

    Arguments:
        graph: the face graph.
        normals: unit face normals, (*batch, F, 3).

    Returns:
        H(P_j) per face, (*batch, F)."""
    d2 = jnp.concatenate([_largest_difference(normals, t) for t in graph.tiers], axis=-1)[..., graph.tier_order]
    spread = jnp.sqrt(jnp.maximum(d2, 0))
    a = normals[..., graph.edge_faces[:, 0], :]
    b = normals[..., graph.edge_faces[:, 1], :]
    phi = jnp.where(graph.edge_mask, jnp.sqrt(jnp.maximum(jnp.sum((a - b) ** 2, axis=-1), 0)), 0)
    pe = jnp.where(graph.patch_edge_mask, phi[..., graph.patch_edges], 0)  # (*b, F, L)
    rtv = jnp.max(pe, axis=-1) / (_EPS + jnp.sum(pe, axis=-1))
    return spread * rtv


def _best_patch(graph: FaceGraph, h: Float[Array, "*batch F"]) -> Int[Array, "*batch F"]:
    """For each face f, the j ∈ N(f) whose patch has the least H."""
    cand = jnp.where(graph.ring_mask, h[..., graph.ring], jnp.inf)       # (*b, F, K)
    slot = jnp.argmin(cand, axis=-1)
    return jnp.take_along_axis(jnp.broadcast_to(graph.ring, cand.shape), slot[..., None], axis=-1)[..., 0]


def guidance_normals(
    graph: FaceGraph, normals: Float[Array, "*batch F 3"], areas: Float[Array, "*batch F"]
) -> Float[Array, "*batch F 3"]:
    """g_f: the area-weighted mean normal of f's most consistent candidate patch.

    Arguments:
        graph: the face graph.
        normals: unit face normals, (*batch, F, 3).
        areas: face areas, (*batch, F).

    Returns:
        The guidance normals g, (*batch, F, 3)."""
    best = _best_patch(graph, jax.lax.stop_gradient(patch_inconsistency(graph, normals)))
    weighted = areas[..., None] * normals
    patch_mean = safe_normalize(slot_sum(lambda s: jnp.where(s[1][:, None], weighted[..., s[0], :], 0),
                                         (graph.ring.T, graph.ring_mask.T), jnp.zeros_like(normals)))   # (*b, F, 3)
    return jnp.take_along_axis(patch_mean, jnp.broadcast_to(best[..., None], patch_mean.shape), axis=-2)


def guided_normal_filtering(
    mesh: Mesh, sigma_s: Scalar = 1.0, sigma_r: Scalar = 0.35, normal_iterations: int = 20,
    vertex_iterations: int = 20, iterations: int = 1, tangential: Scalar = 0.1, graph: FaceGraph | None = None,
) -> Mesh:
    """``iterations`` rounds of (guided normal filter ``normal_iterations``
    times, then ``vertex_iterations`` vertex updates with tangential relaxation
    ``tangential``); module docstring.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        sigma_s: the spatial kernel's width, in units of the mean centroid spacing s̄.
        sigma_r: the range kernel's width on normal differences (dimensionless).
        normal_iterations: normal-filtering passes per round.
        vertex_iterations: vertex-update steps per round.
        iterations: the number of outer iterations (a Python int: the loop is compiled once).
        tangential: the tangential relaxation t per vertex-update step (0 = none).
        graph: the face graph from :func:`~jaxmesh.denoise.face_graph` (built from ``mesh`` when None).

    Returns:
        The denoised mesh."""
    return joint_bilateral_denoising(mesh, guidance_normals, sigma_s, sigma_r, normal_iterations,
                                     vertex_iterations, iterations, tangential, graph)

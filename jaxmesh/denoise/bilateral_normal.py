"""Bilateral filtering of face normals (Zheng, Fu, Au & Tai 2011, the local
iterative scheme), followed by the shared vertex update.

One outer round, from the current positions:

1. face normals n_f, areas A_f, centroids c_f; the spatial weights of the
   vertex ring N(f) (faces sharing a vertex with f, f included)

       W_s(f, g) = exp(−‖c_f − c_g‖² / 2σ_s²),   σ_s = sigma_s · s̄,

   s̄ the mean distance between centroids of edge-adjacent faces (so
   ``sigma_s`` is dimensionless);
2. ``normal_iterations`` passes of the joint bilateral filter

       n_f ← normalize( Σ_{g∈N(f)} A_g W_s(f, g) W_r(‖g_f − g_g‖) n_g ),
       W_r(t) = exp(−t² / 2σ_r²),

   with the guidance g = n itself (plain bilateral filtering: the range kernel
   compares the normals being filtered; ``sigma_r`` is a distance between unit
   vectors, 2 sin(θ/2) for an angle θ);
3. ``vertex_iterations`` steps of :func:`~jaxmesh.denoise.vertex_update`, with
   tangential relaxation ``tangential`` (0.1 by default; 0 is the paper's update).

Differentiable in the positions and in ``sigma_s``, ``sigma_r`` and
``tangential`` (every step is smooth away from zero-area faces).

**Layout.**  The sums over N(f) run one ring slot k at a time, in a loop over the
slots: a gather of the (F, 3) rows ``ring[:, k]`` added into an (F, 3) total
(:func:`jaxmesh._private.slot_sum`).  XLA's CPU backend runs that several times
faster than gathering the whole (F, K, 3) neighbourhood and reducing over K
(``benchmarks/bench_ring_sums.py``).
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .._private import Scalar, dot, lift, safe_normalize, slot_sum
from ..geometry import face_areas, face_normals
from ..mesh import Mesh
from ._loop import check_iterations, iterate
from .face_graph import FaceGraph, centroid_spacing, face_centroids, face_graph
from .vertex_update import vertex_update

__all__ = ["bilateral_normal_filtering", "joint_bilateral_denoising", "spatial_weights",
           "joint_bilateral_normals"]


def spatial_weights(
    mesh: Mesh, graph: FaceGraph, x: Float[Array, "*batch V 3"], sigma_s
) -> Float[Array, "*batch F K"]:
    """A_g W_s(f, g) on the padded ring slots (0 on padding), σ_s = sigma_s · s̄.

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        graph: the face graph.
        x: positions, (*batch, V, 3).
        sigma_s: the spatial kernel's width, in units of the mean centroid spacing s̄.

    Returns:
        (*batch, F, K) weights, 0 on padding slots."""
    geo = mesh.with_vertices(x)
    c = face_centroids(geo)
    s2 = lift((jnp.asarray(sigma_s, x.dtype) * centroid_spacing(graph, c))[..., None] ** 2, c.ndim - 1)
    areas = face_areas(geo)

    def slot(_, ring_mask):                                              # one column k: (*b, F)
        ring, mask = ring_mask
        d = c - c[..., ring, :]
        return None, jnp.where(mask, jnp.exp(-0.5 * dot(d, d) / s2) * areas[..., ring], 0)
    columns = jax.lax.scan(slot, None, (graph.ring.T, graph.ring_mask.T))[1]     # (K, *b, F)
    return jnp.moveaxis(columns, 0, -1)


def joint_bilateral_normals(
    graph: FaceGraph, normals: Float[Array, "*batch F 3"], guidance: Float[Array, "*batch F 3"],
    weights: Float[Array, "*batch F K"], sigma_r, per_face: bool = False,
) -> Float[Array, "*batch F 3"]:
    """normalize( Σ_k weights[f, k] W_r(‖g_f − g_{ring[f,k]}‖) n_{ring[f,k]} ) (module docstring).

    Arguments:
        graph: the face graph.
        normals: unit face normals, (*batch, F, 3).
        guidance: the guidance normals g, (*batch, F, 3).
        weights: the spatial weights on the ring slots, (*batch, F, K) (:func:`spatial_weights`).
        sigma_r: the range kernel's width on normal differences (dimensionless): one per batch
            element, (*batch), or with ``per_face`` one per face, (*batch, F).
        per_face: ``sigma_r`` holds one width per face f (its row's kernel).

    Returns:
        The filtered unit normals, (*batch, F, 3)."""
    sr = jnp.asarray(sigma_r, normals.dtype)
    sr2 = lift(sr if per_face else sr[..., None], normals.ndim - 1) ** 2     # (*b, F) or (*b, 1)

    def term(slot):                                  # one ring slot (module docstring, *Layout*)
        g, w = slot
        diff = guidance - guidance[..., g, :]
        return (w * jnp.exp(-0.5 * dot(diff, diff) / sr2))[..., None] * normals[..., g, :]
    return safe_normalize(slot_sum(term, (graph.ring.T, jnp.moveaxis(weights, -1, 0)), jnp.zeros_like(normals)))


def joint_bilateral_denoising(
    mesh: Mesh, guidance: Callable, sigma_s, sigma_r, normal_iterations: int, vertex_iterations: int,
    iterations: int, tangential, graph: FaceGraph | None,
) -> Mesh:
    """The two-step loop shared by bilateral and guided normal filtering:
    ``iterations`` rounds of (spatial weights at the current positions;
    ``normal_iterations`` passes n ← joint_bilateral_normals(n, guidance(graph, n, areas));
    ``vertex_iterations`` steps of :func:`vertex_update` with ``tangential``).

    Arguments:
        mesh: the mesh (single, or with batched vertices (*batch, V, 3)).
        guidance: maps (graph, normals, areas) to the guidance normals (the normals themselves for the bilateral filter).
        sigma_s: the spatial kernel's width, in units of the mean centroid spacing s̄.
        sigma_r: the range kernel's width on normal differences (dimensionless).
        normal_iterations: normal-filtering passes per round.
        vertex_iterations: vertex-update steps per round.
        iterations: the number of outer iterations (a Python int: the loop is compiled once).
        tangential: the tangential relaxation t per vertex-update step (0 = none).
        graph: the face graph (required).

    Returns:
        The denoised mesh."""
    check_iterations(normal_iterations, "normal_iterations")
    check_iterations(vertex_iterations, "vertex_iterations")
    graph = face_graph(mesh) if graph is None else graph

    def step(x):
        geo = mesh.with_vertices(x)
        w = spatial_weights(mesh, graph, x, sigma_s)
        areas = face_areas(geo)

        def normal_pass(n):
            return joint_bilateral_normals(graph, n, guidance(graph, n, areas), w, sigma_r)

        n = iterate(normal_pass, face_normals(geo), normal_iterations)
        return vertex_update(mesh, x, n, vertex_iterations, tangential=tangential, graph=graph)

    return mesh.with_vertices(iterate(step, mesh.vertices, iterations))


def bilateral_normal_filtering(
    mesh: Mesh, sigma_s: Scalar = 1.0, sigma_r: Scalar = 0.35, normal_iterations: int = 10,
    vertex_iterations: int = 20, iterations: int = 1, tangential: Scalar = 0.1, graph: FaceGraph | None = None,
) -> Mesh:
    """``iterations`` rounds of (bilateral normal filter ``normal_iterations``
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
    return joint_bilateral_denoising(mesh, lambda graph, n, areas: n, sigma_s, sigma_r, normal_iterations,
                                     vertex_iterations, iterations, tangential, graph)

"""Sums over padded neighbourhoods, slot by slot (the library's layout) against the
two other ways of writing them: the umbrella operator K x on the vertex one-rings
(:func:`jaxmesh.denoise.ring_umbrella`) against segment sums over the directed edge
list (:func:`jaxmesh.operators.umbrella`); one joint bilateral normal pass and the
spatial weights on the face rings (:mod:`jaxmesh.denoise.bilateral_normal`) against
a gather of the whole (F, K, 3) neighbourhood reduced over K; the vertex update
(:func:`jaxmesh.denoise.vertex_update`) along the face graph's vertex tables against
segment sums over the face corners.

    .venv/bin/python benchmarks/bench_ring_sums.py [--mesh spot] [--dtype float32]

Steady-state milliseconds per jitted call (each call 20 steps in a ``fori_loop``,
as the filters run them), under the ``jaxmesh`` command's XLA flag
(:mod:`jaxmesh.compiler`), one run of the script.  Compare the ratios.
"""

from __future__ import annotations

import argparse

from jaxmesh.compiler import prefer_fast_cpu_compiles

prefer_fast_cpu_compiles()

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh._private import safe_normalize  # noqa: E402
from jaxmesh.denoise import (face_graph, joint_bilateral_normals, ring_umbrella, spatial_weights,  # noqa: E402
                             vertex_rings, vertex_update)
from jaxmesh.denoise.face_graph import centroid_spacing, face_centroids  # noqa: E402
from jaxmesh.geometry import face_areas, face_normals  # noqa: E402
from jaxmesh.operators import umbrella  # noqa: E402

from bench_dot import ms  # noqa: E402  (same folder)

STEPS = 20


def looped(step):
    """``STEPS`` applications of ``step`` in one compiled loop."""
    return jax.jit(lambda x: jax.lax.fori_loop(0, STEPS, lambda _, y: step(y), x))


def whole_ring_pass(graph, n, w, sigma_r):
    """The joint bilateral pass as one (F, K, 3) gather reduced over K (the other layout)."""
    diff = n[:, None, :] - n[graph.ring, :]
    weight = w * jnp.exp(-0.5 * jnp.sum(diff * diff, axis=-1) / sigma_r ** 2)
    return safe_normalize(jnp.sum(weight[..., None] * n[graph.ring, :], axis=-2))


def whole_ring_weights(mesh, graph, x, sigma_s):
    """The spatial weights from one (F, K, 3) gather of the centroids (the other layout)."""
    geo = mesh.with_vertices(x)
    c = face_centroids(geo)
    s = sigma_s * centroid_spacing(graph, c)
    d = c[:, None, :] - c[graph.ring, :]
    w = jnp.exp(-0.5 * jnp.sum(d * d, axis=-1) / s ** 2) * face_areas(geo)[graph.ring]
    return jnp.where(graph.ring_mask, w, 0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="spot", choices=("bunny", "spot"))
    ap.add_argument("--dtype", default="float32", choices=("float32", "float64"))
    args = ap.parse_args()
    mesh = jaxmesh.data.load_sample(args.mesh, dtype=args.dtype)
    x = mesh.vertices
    rings, graph = vertex_rings(mesh), face_graph(mesh)
    n = face_normals(mesh)
    w = spatial_weights(mesh, graph, x, 1.0)
    np.testing.assert_allclose(whole_ring_pass(graph, n, w, 0.6), joint_bilateral_normals(graph, n, n, w, 0.6),
                               atol=1e-5)
    update = lambda table: jax.jit(lambda y: vertex_update(mesh, y, n, STEPS, tangential=0.1,  # noqa: E731
                                                           graph=table))
    cases = [
        ("vertex update, t = 0.1", "segment sums", update(None), update(graph), x, x),
        ("umbrella K x", "segment sums", looped(lambda y: y + 0.3 * umbrella(mesh, y)),
         looped(lambda y: y + 0.3 * ring_umbrella(rings, y)), x, x),
        ("bilateral normal pass", "(F, K, 3) gather", looped(lambda m: whole_ring_pass(graph, m, w, 0.6)),
         looped(lambda m: joint_bilateral_normals(graph, m, m, w, 0.6)), n, n),
        ("spatial weights", "(F, K, 3) gather", jax.jit(lambda y: whole_ring_weights(mesh, graph, y, 1.0)),
         jax.jit(lambda y: spatial_weights(mesh, graph, y, 1.0)), x, x),
    ]
    print(f"{args.mesh}, {mesh.num_vertices} vertices, {args.dtype}, {STEPS} steps per call "
          "(spatial weights: one)\n")
    print("| sum | other layout | other ms | slot by slot ms | ratio |")
    print("|---|---|---|---|---|")
    for name, other, slow, fast, slow_arg, fast_arg in cases:
        a, b = ms(slow, slow_arg), ms(fast, fast_arg)
        print(f"| {name} | {other} | {a:.2f} | {b:.2f} | {a / b:.1f} |")


if __name__ == "__main__":
    main()

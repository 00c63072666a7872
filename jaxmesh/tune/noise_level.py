"""Estimating the noise level σ of a mesh from the mesh alone.

Model (thesis ch.2 eq.1): y = x + η, η ~ N(0, σ² I) per coordinate, x a smooth
surface.  The umbrella operator K = D⁻¹A − I is a high-pass filter, and K²
more so: on a smooth surface K²x along the normal is a fourth-order term that
is small next to the noise, while for the noise, n_i · (K²η)_i has standard
deviation σ ‖row_i(K²)‖ (K depends on the connectivity only, so the row norms
are exact).  Hence

    σ̂ = 1.4826 · MAD_i( n_i · (K² y)_i / ‖row_i(K²)‖ ),

the median absolute deviation making the estimate robust to the vertices where
the surface is not smooth (creases, corners, boundaries).  n_i are the noisy
mesh's area-weighted vertex normals.

Measured (``experiments/tune/run.py``): within ~10% of the true σ at
0.1 and 0.3 mean edge lengths on the shared meshes; at 0.02 ℓ̄ the surface's
own fine detail dominates and σ̂ can be 1.5–3× too large on detailed scans.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..geometry import vertex_normals
from ..mesh import Mesh
from ..operators import umbrella

__all__ = ["estimate_noise", "umbrella_square_row_norms"]

_MAD_TO_SIGMA = 1.482602218505602  # 1 / Φ⁻¹(3/4)


def umbrella_square_row_norms(mesh: Mesh) -> np.ndarray:
    """‖row_i(K²)‖ for every vertex (host, scipy; 0 for isolated vertices)."""
    from ..sparse import umbrella_matrix

    k = umbrella_matrix(mesh)
    k2 = (k @ k).tocsr()
    return np.sqrt(np.asarray(k2.multiply(k2).sum(axis=1)).ravel())


def estimate_noise(mesh: Mesh) -> float:
    """σ̂ of the module docstring, in the mesh's units (equivariant: scaling the
    mesh by s scales σ̂ by s; translation and rotation leave it unchanged)."""
    if mesh.batch_shape:
        raise ValueError("estimate_noise takes one mesh; loop over a batch")
    g = umbrella_square_row_norms(mesh)
    y = mesh.vertices
    s = jnp.sum(umbrella(mesh, umbrella(mesh, y)) * vertex_normals(mesh, "area"), axis=-1)
    ok = g > 0
    if not ok.any():
        raise ValueError("estimate_noise: the mesh has no vertex with neighbours")
    r = np.asarray(s, dtype=np.float64)[ok] / g[ok]
    return float(_MAD_TO_SIGMA * np.median(np.abs(r - np.median(r))))

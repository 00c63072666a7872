"""Is a clean scan's own vertex-scale roughness distinguishable from noise by its
spatial correlation?  For z_i = n_i · (K² y)_i / ‖row_i(K²)‖ (the umbrella
estimator's residual, ``jaxmesh.tune.noise_level``) this prints, per mesh, the
correlation of z between neighbours (lag 1) and between vertices two edges
apart (lag 2), on the clean mesh and for independent unit noise along its
normals.  The ``noise_level`` docstring quotes it.  Then, whether a sharper
high-pass would leave less of the roughness: the "flat" statistic (10%
quantile of the 2-ring patch means of z², calibrated by unit noise along the
normals) of the clean mesh, in ℓ̄, with K^p in place of K², p = 1..6.

    .venv/bin/python experiments/denoise/roughness_correlation.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

from jaxmesh.geometry import mean_edge_length, vertex_normals  # noqa: E402
from jaxmesh.sparse import adjacency_matrix  # noqa: E402
from jaxmesh.tune.noise_level import _normal_high_pass, umbrella_square_row_norms  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load as load_shared  # noqa: E402

MESHES = ("cow", "maxplanck", "fertility", "human", "fandisk", "bunny")


def lag_covariances(mesh, z: np.ndarray) -> tuple[float, float, float]:
    """Mean z², mean z_i z_j over neighbours, mean over vertices two edges apart."""
    a = adjacency_matrix(mesh).tocsr()
    a.data[:] = 1
    a2 = (a @ a).tocsr()
    a2.setdiag(0)
    a2 = (a2 - a.multiply(a2 > 0)).tocsr()
    a2.data[:] = 1
    a2.eliminate_zeros()
    return float(np.mean(z * z)), float(z @ (a @ z)) / a.nnz, float(z @ (a2 @ z)) / a2.nnz


def order_readings(mesh, orders=range(1, 7), quantile: float = 0.1) -> list[float]:
    """The clean mesh's "flat" reading, in ℓ̄, with the high-pass K^p for each p."""
    from jaxmesh.host import HostMesh
    from jaxmesh.tune.noise_level import _patch_statistic, projection_normals
    import scipy.sparse as sp

    host = HostMesh(mesh)
    k = host.umbrella
    n = np.asarray(projection_normals(host), np.float64)
    y = np.asarray(mesh.vertices, np.float64)
    ring = (host.two_ring + sp.identity(mesh.num_vertices, format="csr")).tocsr()
    unit = np.random.default_rng(0).standard_normal((3, len(y), 1)) * n
    kp, out = sp.identity(len(y), format="csr"), []
    for p in range(1, max(orders) + 1):
        kp = (k @ kp).tocsr()
        g = np.sqrt(np.asarray(kp.multiply(kp).sum(axis=1)).ravel())
        ok = g > 0
        gs = np.where(ok, g, 1.0)
        stat = lambda u: _patch_statistic((np.sum((kp @ u) * n, axis=1) / gs) ** 2, ring, ok, quantile)  # noqa: E731
        if p in orders:
            out.append(float(np.sqrt(stat(y) / np.mean([stat(u) for u in unit]))) / float(mean_edge_length(mesh)))
    return out


def main() -> None:
    print("mesh | clean: sqrt(C0)/ℓ̄, lag-1, lag-2 correlation | independent noise: lag-1, lag-2")
    for name in MESHES:
        clean = load_shared(name)
        ell = float(mean_edge_length(clean))
        g = umbrella_square_row_norms(clean)
        normals = vertex_normals(clean, "area")
        noise = np.random.default_rng(1).standard_normal((len(g), 1)) * np.asarray(normals)
        c = lag_covariances(clean, _normal_high_pass(clean, clean.vertices, normals) / g / ell)
        n = lag_covariances(clean, _normal_high_pass(clean, noise, normals) / g)
        print(f"{name} | {np.sqrt(c[0]):.4f}, {c[1] / c[0]:+.3f}, {c[2] / c[0]:+.3f} | "
              f"{n[1] / n[0]:+.3f}, {n[2] / n[0]:+.3f}")
    print("\nmesh | the clean mesh's flat reading (ℓ̄) with K^1 .. K^6")
    for name in MESHES:
        print(f"{name} | " + " ".join(f"{r:.4f}" for r in order_readings(load_shared(name))), flush=True)


if __name__ == "__main__":
    main()

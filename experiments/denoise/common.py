"""Shared setup of the denoising experiments: meshes, noise, parameter grids
for every jaxmesh method (evaluated as one batched call per static setting)
and the peers (trimesh, Open3D, PyMeshLab), all tuned with the clean mesh in hand."""

from __future__ import annotations

import itertools
import sys
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxmesh  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load as load_shared  # noqa: E402
from jaxmesh.denoise import METHODS, face_graph  # noqa: E402
from jaxmesh.metrics import mean_normal_angle_error, visual_error  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "experiments" / "results" / "denoise"
SIGMAS = (0.02, 0.1, 0.3)
TABLE_MESHES = ("cow", "spot", "fandisk", "maxplanck", "camelhead", "bunny")

LOG = np.logspace
BOUNDARY = ("free", "curve")


def load(name: str) -> jaxmesh.Mesh:
    """A shared mesh scaled to a unit bounding-box diagonal."""
    return jaxmesh.normalize(load_shared(name))


def noisy_copy(clean: jaxmesh.Mesh, sigma: float, seed: int = 0) -> jaxmesh.Mesh:
    return jaxmesh.add_noise(clean, sigma, jax.random.PRNGKey(seed))


# For each method: static settings (ints / choices) x a grid of continuous values
# evaluated in one batched call (one batch element per grid point).
GRIDS = {
    "kernel": ([{"iterations": k} for k in (2, 5, 10)], {"lam": LOG(-1.3, 1.3, 14)}),
    "cauchy_diffusion": ([{"iterations": k} for k in (5, 10, 20)],
                    {"dt": (0.1, 0.25, 0.5), "c": LOG(-1, 1, 5)}),
    "umbrella_flow": ([{"iterations": k, "boundary": b} for k in (1, 2, 3, 5, 10, 20) for b in BOUNDARY],
                  {"lam": LOG(-1.7, 0, 10)}),
    "hc": ([{"iterations": k, "boundary": b} for k in (1, 2, 5, 10, 20, 40) for b in BOUNDARY],
           {"alpha": (0.0, 0.1, 0.2, 0.3), "beta": (0.3, 0.5, 0.7, 0.9)}),
    "taubin": ([{"iterations": k, "boundary": b} for k in (1, 2, 5, 10, 20, 40, 80) for b in BOUNDARY],
               {"lam": (0.05, 0.1, 0.3, 0.5, 0.7), "kpb": (0.02, 0.05, 0.1)}),
    "cotangent": ([{"iterations": k} for k in (1, 2, 3, 5, 10)], {"dt": LOG(-1.7, 0, 10)}),
    "cotangent_implicit": ([{"iterations": k} for k in (1, 3)], {"dt": LOG(-2.5, 0.7, 12)}),
    "normal_mean": ([{"normal_iterations": a, "vertex_iterations": b}
                     for a, b in itertools.product((1, 2, 5, 10), (1, 3, 10, 20))], {}),
    "normal_median": ([{"normal_iterations": a, "vertex_iterations": b}
                       for a, b in itertools.product((1, 2, 5, 10), (1, 3, 10, 20))], {}),
    "bilateral": ([{"iterations": k} for k in (1, 2, 3, 5)],
                  {"sigma_c": (0.3, 0.5, 1.0, 2.0), "sigma_s": (0.05, 0.2, 0.5, 1.0, 2.0)}),
    "geometric": ([{"iterations": k} for k in (1, 3)], {"dt": LOG(-2.5, 0.5, 8), "rho": (0.3, 1.0, 3.0)}),
}


def _product(cont: dict) -> list[dict]:
    keys = list(cont)
    return [dict(zip(keys, vals)) for vals in itertools.product(*(cont[k] for k in keys))] or [{}]


def _to_params(name: str, point: dict) -> dict:
    p = dict(point)
    if name == "taubin":  # pass-band k_PB = 1/λ + 1/μ  =>  μ = λ / (k_PB λ - 1)
        kpb = p.pop("kpb")
        p["mu"] = p["lam"] / (kpb * p["lam"] - 1)
    return p


def evaluate_method(name: str, clean, noisy, rings=None):
    """Every grid point of ``name`` on ``noisy``: list of (params, E, angle, seconds)."""
    statics, cont = GRIDS[name]
    points = [_to_params(name, q) for q in _product(cont)]
    rows = []
    for static in statics:
        aux = {"graph": rings} if "graph" in METHODS[name].params else {}
        if points[0]:
            b = len(points)
            batch = noisy.with_vertices(jnp.broadcast_to(noisy.vertices, (b,) + noisy.vertices.shape))
            vals = {k: jnp.asarray([p[k] for p in points]) for k in points[0]}
        else:
            batch, vals = noisy, {}
        t = time.perf_counter()
        out = METHODS[name](batch, **static, **vals, **aux)
        e = np.atleast_1d(np.asarray(visual_error(clean, out)))
        a = np.atleast_1d(np.asarray(mean_normal_angle_error(clean, out)))
        sec = (time.perf_counter() - t) / max(len(points), 1)
        for k, p in enumerate(points):
            rows.append(({**static, **p}, float(e[k]), float(a[k]), sec))
    return rows


# ------------------------------------------------------------------ peers

def _trimesh(name, clean, noisy):
    import trimesh.smoothing as sm

    v0, f = np.asarray(noisy.vertices), np.asarray(noisy.faces)
    grids = {
        "trimesh laplacian": [(sm.filter_laplacian, dict(lamb=l, iterations=k, volume_constraint=False))
                              for l in (0.02, 0.05, 0.1, 0.3, 0.5, 0.8) for k in (1, 2, 3, 5, 10, 20)],
        "trimesh taubin": [(sm.filter_taubin, dict(lamb=l, nu=n * l / 0.5, iterations=k))
                           for l in (0.05, 0.1, 0.3, 0.5, 0.7) for n in (0.51, 0.53, 0.6)
                           for k in (1, 2, 5, 10, 20, 40)],
        "trimesh HC": [(sm.filter_humphrey, dict(alpha=a, beta=b, iterations=k))
                       for a in (0.0, 0.1, 0.3) for b in (0.3, 0.5, 0.8) for k in (1, 2, 5, 10, 20, 40)],
    }
    import trimesh

    for fn, kw in grids[name]:
        m = trimesh.Trimesh(v0.copy(), f, process=False)
        t = time.perf_counter()
        fn(m, **kw)
        yield kw, np.asarray(m.vertices), time.perf_counter() - t


def _open3d(name, clean, noisy):
    import open3d as o3d

    v0, f = np.array(noisy.vertices, np.float64), np.array(noisy.faces, np.int32)
    grids = {
        "Open3D laplacian": [("filter_smooth_laplacian", dict(number_of_iterations=k, lambda_filter=l))
                             for l in (0.02, 0.05, 0.1, 0.3, 0.5, 0.8) for k in (1, 2, 3, 5, 10, 20)],
        "Open3D taubin": [("filter_smooth_taubin", dict(number_of_iterations=k, lambda_filter=l, mu=-m * l / 0.5))
                          for l in (0.05, 0.1, 0.3, 0.5, 0.7) for m in (0.51, 0.53, 0.6)
                          for k in (1, 2, 5, 10, 20, 40)],
    }
    for fn, kw in grids[name]:
        m = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(v0), o3d.utility.Vector3iVector(f))
        t = time.perf_counter()
        out = getattr(m, fn)(**kw)
        yield kw, np.asarray(out.vertices), time.perf_counter() - t


def _pymeshlab(name, clean, noisy):
    import pymeshlab as ml

    v0, f = np.asarray(noisy.vertices), np.asarray(noisy.faces)
    grids = {
        "MeshLab cot. laplacian": [("apply_coord_laplacian_smoothing", dict(stepsmoothnum=k, cotangentweight=True))
                                   for k in (1, 2, 3, 5, 10)],
        "MeshLab taubin": [("apply_coord_taubin_smoothing", dict(lambda_=l, mu=-m * l / 0.5, stepsmoothnum=k))
                           for l in (0.05, 0.1, 0.3, 0.5, 0.7) for m in (0.51, 0.53, 0.6)
                           for k in (1, 2, 5, 10, 20, 40)],
        "MeshLab two-step": [("apply_coord_two_steps_smoothing",
                              dict(stepsmoothnum=s, normalthr=t, stepnormalnum=n, stepfitnum=fit))
                             for s in (1, 3) for t in (30.0, 60.0) for n in (5, 20) for fit in (5, 20)],
    }
    for fn, kw in grids[name]:
        ms = ml.MeshSet()
        ms.add_mesh(ml.Mesh(vertex_matrix=v0.copy(), face_matrix=f.astype(np.int32)))
        t = time.perf_counter()
        getattr(ms, fn)(**kw)
        out = ms.current_mesh().vertex_matrix()
        yield kw, np.asarray(out), time.perf_counter() - t


PEERS = {
    "trimesh laplacian": _trimesh, "trimesh taubin": _trimesh, "trimesh HC": _trimesh,
    "Open3D laplacian": _open3d, "Open3D taubin": _open3d,
    "MeshLab cot. laplacian": _pymeshlab, "MeshLab taubin": _pymeshlab, "MeshLab two-step": _pymeshlab,
}


def refine(name: str, clean, noisy, best: dict, rings=None, steps: int = 9, spread: float = 1.6):
    """A finer batched grid around the best grid point (same static setting):
    each continuous parameter p in [p / spread, p * spread] (log spacing)."""
    statics, _ = GRIDS[name]
    static = {k: best[k] for k in statics[0]}
    cont = {k: v for k, v in best.items() if k not in static}
    if not cont:
        return []
    axes = {k: np.asarray(v) * LOG(-np.log10(spread), np.log10(spread), steps) for k, v in cont.items()}
    if name == "taubin":   # keep μ < -λ: refine λ and μ jointly along their own axes
        axes = {"lam": axes["lam"], "mu": axes["mu"]}
    points = _product(axes)
    if name == "taubin":
        points = [p for p in points if p["mu"] < -p["lam"]]
    b = len(points)
    batch = noisy.with_vertices(jnp.broadcast_to(noisy.vertices, (b,) + noisy.vertices.shape))
    vals = {k: jnp.asarray([p[k] for p in points]) for k in points[0]}
    aux = {"graph": rings} if "graph" in METHODS[name].params else {}
    out = METHODS[name](batch, **static, **vals, **aux)
    e, a = np.asarray(visual_error(clean, out)), np.asarray(mean_normal_angle_error(clean, out))
    return [({**static, **p}, float(e[k]), float(a[k]), float("nan")) for k, p in enumerate(points)]


def evaluate_peer(name: str, clean, noisy):
    rows = []
    try:
        runs = list(PEERS[name](name, clean, noisy))
    except ImportError as err:
        print(f"  skipping {name}: {err} (pip install '.[bench]')")
        return rows
    for kw, v, sec in runs:
        if v.shape != tuple(noisy.vertices.shape):
            raise RuntimeError(f"{name} changed the vertex count: cannot compare by correspondence")
        x = jnp.asarray(v)
        rows.append((kw, float(visual_error(clean, x)), float(mean_normal_angle_error(clean, x)), sec))
    return rows


def rings_for(mesh):
    """The host-built face graph that the normal-filtering methods need under jit."""
    return face_graph(mesh)

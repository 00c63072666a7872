"""Thesis figs 5.2–5.19 for every mesh in ../shared/meshes: the six-panel figure
(render, Laplacian spectra, degree distribution, K_nn(k), C(k) both ways,
geodesic distance distributions) and a summary table; plus the accuracy of
the three geodesic estimates against exact geodesic paths (edge-flip
geodesics of Sharp & Crane 2020 through potpourri3d, optional) on a seeded
sample of vertex pairs.

    .venv/bin/python experiments/stats/run.py [--meshes cow bunny ...] [--sources 200] [--figures-only]

writes experiments/results/stats/<mesh>.png, summary.md and geodesic_error.md (only the
figures with --figures-only, leaving the tables of every mesh as they are).
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh import stats  # noqa: E402
from jaxmesh.geodesics import heat_distances  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT.parent / "shared" / "meshes"
OUT = ROOT / "experiments" / "results" / "stats"
UP = {"fandisk": "y", "maxplanck": "z", "fertility": "z", "igea": "y", "armadillo": "y"}


def geodesic_errors(mesh, pairs: int, seed: int) -> dict[str, np.ndarray]:
    """Relative error (estimate - exact) / exact of each method on seeded pairs."""
    import potpourri3d as pp3d

    v, f = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces)
    rng = np.random.default_rng(seed)
    src = np.sort(rng.choice(len(v), size=20, replace=False))
    tgt = rng.choice(len(v), size=(20, pairs // 20))
    solver = pp3d.EdgeFlipGeodesicSolver(v, f)
    exact = np.array([[np.linalg.norm(np.diff(solver.find_geodesic_path(int(s), int(t)), axis=0), axis=1).sum()
                       for t in row] for s, row in zip(src, tgt)])
    est = {"edges": stats.graph_distances(mesh, src), "knn": stats.graph_distances(mesh, src, "knn"),
           "heat": stats.heat_geodesics(mesh, src),
           # the former statistic: the mesh's own triangles, Neumann boundary
           "heat_own": np.asarray(heat_distances(mesh, src, boundary="neumann", intrinsic=False))}
    ok = exact > 0
    return {k: ((d[np.arange(20)[:, None], tgt] - exact) / np.where(ok, exact, 1))[ok] for k, d in est.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--meshes", nargs="+", default=sorted(p.stem for p in SHARED.glob("*.ply")))
    ap.add_argument("--sources", type=int, default=200)
    ap.add_argument("--pairs", type=int, default=400)
    ap.add_argument("--figures-only", action="store_true", help="redraw the figures, leave the tables")
    args = ap.parse_args()
    if not SHARED.is_dir():
        raise SystemExit(f"{SHARED} not found: these experiments need ../shared/meshes beside the repo")
    OUT.mkdir(parents=True, exist_ok=True)
    rows, errs = [], []
    for name in args.meshes:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", jaxmesh.MeshWarning)
            mesh = jaxmesh.load(SHARED / f"{name}.ply", dtype=np.float64)
        t = time.perf_counter()
        st = stats.mesh_statistics(mesh, sources=args.sources, seed=0)
        sec = time.perf_counter() - t
        stats.plot_statistics(mesh, st, title=name, path=OUT / f"{name}.png", up=UP.get(name, "y"))
        s = st["summary"]
        diag = float(jaxmesh.bounding_box_diagonal(mesh))
        rows.append((name, s, sec, diag))
        print(f"{name}: {sec:.1f} s", flush=True)
        if args.figures_only:
            continue
        try:
            errs.append((name, geodesic_errors(mesh, args.pairs, seed=0)))
        except ImportError:
            pass
        except RuntimeError as err:   # geometry-central refuses non-manifold meshes
            print(f"  no exact geodesics for {name}: {str(err).splitlines()[0][-120:]}")
    if args.figures_only:
        return
    lines = ["# Mesh statistics (thesis ch.5)", "",
             "Regenerate: `.venv/bin/python experiments/stats/run.py`. "
             f"{args.sources} seeded geodesic sources (seed 0); geodesic distances as a fraction of the "
             "bounding-box diagonal. Clustering: the general definition (edges among neighbours); "
             "'differ' counts vertices where the thesis's 2/(d-1) gives another value.", "",
             "| mesh | V | avg degree | degree-6 share | assortativity r | mean clustering | thesis 2/(d-1) | differ | "
             "geodesic mean (edges / kNN / heat) | geodesic std (heat) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for name, s, sec, diag in rows:
        g = " / ".join(f"{s[f'geodesic_{k}_mean'] / diag:.3f}" for k in ("edges", "knn", "heat"))
        lines.append(f"| {name} | {s['vertices']} | {s['average_degree']:.3f} | {s['degree_6_share']:.3f} | "
                     f"{s['assortativity']:.3f} | {s['mean_clustering']:.3f} | {s['mean_thesis_clustering']:.3f} | "
                     f"{s['clustering_formulas_differ_at']} | {g} | {s['geodesic_heat_std'] / diag:.3f} |")
    (OUT / "summary.md").write_text("\n".join(lines) + "\n")
    if errs:
        lines = ["# Geodesic estimates against exact geodesic paths", "",
                 f"Relative error (estimate − exact) / exact on {args.pairs} seeded vertex pairs per mesh "
                 "(20 sources); exact = edge-flip geodesics (Sharp & Crane 2020, potpourri3d).", "",
                 "Heat method: on the intrinsic Delaunay triangulation with the averaged boundary "
                 "condition (the statistic), and on the mesh's own triangles with the "
                 "Neumann condition (before).", "",
                 "| mesh | edge graph mean / max | kNN graph (k=8) mean / min | heat, intrinsic Delaunay: "
                 "mean abs / max abs | heat, own triangles (before): mean abs / max abs |",
                 "|---|---|---|---|---|"]
        for name, e in errs:
            lines.append(f"| {name} | {e['edges'].mean():+.2%} / {e['edges'].max():+.2%} | "
                         f"{e['knn'].mean():+.2%} / {e['knn'].min():+.2%} | "
                         f"{np.abs(e['heat']).mean():.2%} / {np.abs(e['heat']).max():.2%} | "
                         f"{np.abs(e['heat_own']).mean():.2%} / {np.abs(e['heat_own']).max():.2%} |")
        (OUT / "geodesic_error.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()

"""jaxmesh.vf against libigl on the twelve shared meshes: the largest difference of
each libigl-convention function, relative to libigl's largest entry, and the time
of each side.  Writes experiments/results/vf/libigl.md.

    .venv/bin/pip install libigl && .venv/bin/python experiments/vf/libigl_table.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)   # read the files unrounded
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import MESHES, ROOT, load, timed  # noqa: E402

from jaxmesh import vf  # noqa: E402


def rel(a, b) -> float:
    if hasattr(b, "tocsr"):
        a, b = a.tocsr().astype(np.float64), b.tocsr().astype(np.float64)
        return float(abs(a - b).max() / max(abs(b).max(), 1e-300))
    return float(np.abs(np.asarray(a) - b).max() / max(np.abs(b).max(), 1e-300))


def main() -> None:
    import igl

    cases = {
        "cotmatrix": (lambda V, F: vf.cotmatrix(V, F), lambda V, F: igl.cotmatrix(V, F)),
        "massmatrix (Voronoi)": (lambda V, F: vf.massmatrix(V, F), lambda V, F: igl.massmatrix(V, F)),
        "massmatrix (barycentric)": (lambda V, F: vf.massmatrix(V, F, "barycentric"),
                                     lambda V, F: igl.massmatrix(V, F, igl.MASSMATRIX_TYPE_BARYCENTRIC)),
        "adjacency_matrix": (lambda V, F: vf.adjacency_matrix(F), lambda V, F: igl.adjacency_matrix(F)),
        "per_face_normals": (vf.per_face_normals, igl.per_face_normals),
        "per_vertex_normals (area)": (vf.per_vertex_normals, igl.per_vertex_normals),
        "per_vertex_normals (angle)": (lambda V, F: vf.per_vertex_normals(V, F, "angle"),
                                       lambda V, F: igl.per_vertex_normals(V, F, igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_ANGLE)),
        "doublearea": (vf.doublearea, igl.doublearea),
    }
    rows, worst, t_ours, t_again, t_igl = [], {k: 0.0 for k in cases}, 0.0, 0.0, 0.0
    for name in MESHES:
        mesh = load(name)
        V, F = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
        errs = []
        for key, (ours, theirs) in cases.items():
            a, ta = timed(ours, V, F)
            _, t2 = timed(ours, V, F)      # again: the programs for this size are compiled
            b, tb = timed(theirs, V, F)
            t_ours, t_again, t_igl = t_ours + ta, t_again + t2, t_igl + tb
            e = rel(a, b)
            worst[key] = max(worst[key], e)
            errs.append(e)
        loops, ref = vf.boundary_loops(F), igl.boundary_loop_all(F)
        same = sorted(map(len, loops)) == sorted(map(len, ref))
        longest = igl.boundary_loop(F)
        if len(longest):
            mine = vf.boundary_loop(F)
            k = int(np.flatnonzero(mine == longest[0])[0])
            same &= bool(np.array_equal(np.roll(mine, -k), longest))
        rows.append(f"| {name} | " + " | ".join(f"{e:.1e}" for e in errs) + f" | {len(loops)} {'=' if same else '≠'} |")
        print(rows[-1], flush=True)
    head = "| mesh | " + " | ".join(cases) + " | boundary loops |\n|---|" + "---|" * (len(cases) + 1)
    text = ["# jaxmesh.vf against libigl", "",
            f"libigl {getattr(igl, '__version__', '?')}; the largest difference of each function, relative to "
            "libigl's largest entry (float64).  Boundary loops: the count, and `=` when every loop has libigl's "
            "length and the longest is libigl's cycle in libigl's direction.", "",
            "Rerun: `.venv/bin/python experiments/vf/libigl_table.py`", "", head, *rows, "",
            "Worst over the meshes: " + ", ".join(f"{k} {v:.1e}" for k, v in worst.items()) + ".", "",
            f"Total time over every call: jaxmesh.vf {t_ours:.1f} s the first time on each mesh (JAX compiles "
            f"its operations for each new size), {t_again:.1f} s called again; libigl {t_igl:.1f} s.  "
            "Each call validates the mesh and builds its topology; where speed matters, build a `Mesh` once "
            "and use the JAX functions.", ""]
    out = ROOT / "experiments" / "results" / "vf" / "libigl.md"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(text))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()

"""Heat distances and the statistics in float32 against float64 on every shared mesh.

    .venv/bin/python experiments/stats/float32.py [--meshes spot bunny ...]

For each mesh: the heat-method distances from 8 sources spread over the vertex list, and
the scalar summary of :func:`jaxmesh.stats.mesh_statistics` (200 sources), computed on the
mesh in float64 (x64 on) and in float32 in a child process with x64 off, as a user of the
library's default dtype runs them.  Reported:
the largest difference relative to the largest float64 value (distances), the largest
relative difference over the summary's numbers, or the error float32 was refused with.

Writes experiments/results/stats/float32.md.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import jax

CHILD = len(sys.argv) > 1 and sys.argv[1] == "--child"
jax.config.update("jax_enable_x64", not CHILD)

import numpy as np  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh.geodesics import heat_distances  # noqa: E402
from jaxmesh.stats import mesh_statistics  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import MESHES, load  # noqa: E402

OUT = Path(__file__).resolve().parents[1] / "results" / "stats" / "float32.md"


def _both(what: str, mesh64, name: str):
    """(the float32 result from a child process without x64, or its refusal's message; the float64 one)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out.npz"
        run = subprocess.run([sys.executable, __file__, "--child", what, name, str(out)], capture_output=True,
                             text=True, env={**os.environ, "JAX_ENABLE_X64": "0"})
        if run.returncode:
            raise SystemExit(run.stderr)
        low = dict(np.load(out, allow_pickle=False))
    low = str(low["error"]) if "error" in low else low["value"] if what == "distances" else json.loads(
        str(low["value"]))
    return low, (_distances(mesh64) if what == "distances" else _summary(mesh64))


def _child(what: str, name: str, out: str) -> None:
    mesh = load(name)
    mesh = jaxmesh.Mesh.from_arrays(np.asarray(mesh.vertices, np.float32), mesh.faces, warn=False)
    assert mesh.dtype == np.float32
    try:
        value = _distances(mesh) if what == "distances" else json.dumps(_summary(mesh))
        np.savez(out, value=value)
    except ValueError as err:
        np.savez(out, error=str(err))


def _distances(mesh):
    src = np.arange(0, mesh.num_vertices, max(1, mesh.num_vertices // 8))[:8]
    return np.asarray(heat_distances(mesh, src))


def _summary(mesh):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", jaxmesh.MeshWarning)
        s = mesh_statistics(mesh)["summary"]
    return {k: float(v) for k, v in s.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}


def _cell(low, high, measure) -> str:
    if isinstance(low, str):
        return "refused: " + ("names float64" if "float64" in low else low[:60])
    return f"{measure(low, high):.1e}"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--meshes", nargs="*", default=list(MESHES))
    args = ap.parse_args()
    rows = ["# Heat distances and statistics: float32 against float64", "",
            "Regenerate: `.venv/bin/python experiments/stats/float32.py` (needs ../shared/meshes).", "",
            "Distances: max |d₃₂ − d₆₄| / max d₆₄ over 8 sources. Statistics: the largest relative "
            "difference over the numbers of `mesh_statistics`' summary (200 sources). The target: within 1e-3, "
            "or a clear error naming float64.", "",
            "| mesh | vertices | distances | statistics | seconds |", "|---|---|---|---|---|"]
    for name in args.meshes:
        start = time.perf_counter()
        mesh = load(name)
        finite = lambda a, b: np.abs(a - b)[np.isfinite(b)].max() / np.abs(b[np.isfinite(b)]).max()  # noqa: E731
        d = _cell(*_both("distances", mesh, name), finite)
        rel = lambda a, b: max(abs(a[k] - b[k]) / max(abs(b[k]), 1e-12) for k in b)  # noqa: E731
        s = _cell(*_both("summary", mesh, name), rel)
        rows.append(f"| {name} | {mesh.num_vertices} | {d} | {s} | {time.perf_counter() - start:.0f} |")
        print(rows[-1], flush=True)
    OUT.write_text("\n".join(rows) + "\n")


if __name__ == "__main__":
    _child(*sys.argv[2:5]) if CHILD else main()

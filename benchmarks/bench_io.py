"""Reading meshes: ``jaxmesh.load`` against trimesh's loader on the same files, in one run.

    .venv/bin/python benchmarks/bench_io.py [--mesh igea] [--repeat 5]

The shared mesh (``../shared/meshes/``; default the 134k-vertex igea) is written as OBJ
twice, by ``jaxmesh.save`` (every coordinate ``%.17g``, lossless) and by trimesh's
exporter (shorter numbers), and as OFF and PLY by ``jaxmesh.save``.  Each file is read
by ``jaxmesh.load`` (strict: it refuses malformed files; the plain-OBJ fast path where
the file allows it; for OBJ also the text reader alone, bytes to arrays, without the
mesh's topology) and by ``trimesh.load(..., process=False)``; the median of
``--repeat`` reads is reported, and the ratio jaxmesh / trimesh.  Both results are
checked to hold the same vertices and faces.  Not part of the test suite: numbers
depend on the machine; compare the ratios.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

import jaxmesh
from jaxmesh._meshtext import read_obj

SHARED = Path(__file__).resolve().parents[2] / "shared" / "meshes"


def median_seconds(fn, repeat: int):
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="igea", help="a mesh of ../shared/meshes (its name without .ply)")
    ap.add_argument("--repeat", type=int, default=9)
    args = ap.parse_args()
    source = SHARED / f"{args.mesh}.ply"
    if not source.is_file():
        raise SystemExit(f"{source}: not found (the shared meshes sit beside the repository)")
    mesh = jaxmesh.load(source)
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        files = {"OBJ, written by jaxmesh (%.17g)": Path(tmp) / "a.obj", "OFF, written by jaxmesh": Path(tmp) / "a.off",
                 "PLY (binary), written by jaxmesh": Path(tmp) / "a.ply"}
        for path in files.values():
            jaxmesh.save(mesh, path)
        short = Path(tmp) / "b.obj"
        trimesh.Trimesh(v, f, process=False).export(short)
        files["OBJ, written by trimesh"] = short
        for label, path in files.items():
            if path.suffix == ".obj":      # the text reader alone: no Mesh, no topology (as trimesh's process=False)
                data = path.read_bytes()
                t_read, _ = median_seconds(lambda: read_obj(data), args.repeat)
                rows.append((f"{label}: the text reader alone (bytes to arrays)", len(data) / 1e6, t_read, None))
            t_ours, ours = median_seconds(lambda: jaxmesh.load(path), args.repeat)
            t_tm, theirs = median_seconds(lambda: trimesh.load(path, process=False, force="mesh"), args.repeat)
            assert np.array_equal(np.asarray(ours.faces), np.asarray(theirs.faces))
            np.testing.assert_allclose(np.asarray(ours.vertices), np.asarray(theirs.vertices), rtol=1e-6)
            rows.append((label, path.stat().st_size / 1e6, t_ours, t_tm))
            if rows[-2][3] is None:
                rows[-2] = rows[-2][:3] + (t_tm,)
    print(f"# reading {args.mesh} ({len(v)} vertices, {len(f)} faces), median of {args.repeat}\n")
    print("| file | MB | jaxmesh.load s | trimesh.load s | jaxmesh / trimesh |")
    print("|---|---|---|---|---|")
    for label, mb, a, b in rows:
        print(f"| {label} | {mb:.1f} | {a:.3f} | {b:.3f} | {a / b:.2f} |")


if __name__ == "__main__":
    main()

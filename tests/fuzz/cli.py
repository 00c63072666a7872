"""Fuzz suite: tiny and degenerate meshes through every CLI command and every denoiser.

Case ``i`` runs ``jaxmesh.cli.main(argv)`` in-process for one (mesh, command)
pair.  Outcomes: ``valid`` (exit 0 and the output file, if any, loads),
``error`` (exit 1 with exactly one ``jaxmesh: error: …`` line on stderr),
``traceback`` (an exception escapes ``main``, or exit 1 without that one
line), ``silent`` (exit 0 but the output is missing or unreadable, or a
non-finite mesh).
"""

from __future__ import annotations

import atexit
import contextlib
import io
import shutil
import tempfile
from pathlib import Path

import numpy as np

MESHES = {
    "triangle": ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]),
    "two_triangles": ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [[0, 1, 2], [1, 3, 2]]),
    "tetrahedron": ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]),
    "sliver": ([[0, 0, 0], [1, 0, 0], [0.5, 1e-17, 0], [0.5, 0.5, 1]], [[0, 1, 2], [0, 1, 3], [1, 2, 3], [2, 0, 3]]),
    "isolated_vertex": ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [5, 5, 5]],
                        [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]),
    "fin": ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], [[0, 1, 2], [1, 0, 3], [0, 1, 4]]),
    "octahedron": ([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
                   [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]),
    "flat_zero_area": ([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]], [[0, 1, 2], [0, 1, 3]]),
    # dirty scans, as a new user meets them
    "duplicate_faces": ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                        [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [1, 2, 3]]),
    "seam_copies": ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.3]],
                    [[0, 1, 2], [3, 5, 4]]),
    "vertex_soup": ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [3, 4, 5]]),
    "inconsistent_orientation": ([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
                                 [[0, 4, 2], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5],
                                  [0, 3, 5]]),
    "isolated_triangles": ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [10, 0, 0], [11, 0, 0], [10, 1, 0.5]],
                           [[0, 1, 2], [3, 4, 5]]),
    "hole": ([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
             [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5]]),
    "collinear": ([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], [[0, 1, 2], [1, 2, 3], [0, 2, 3]]),
    "far_coordinate": ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1e30, 0, 0]],
                       [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [1, 4, 2]]),
}


def _commands():
    from jaxmesh.denoise import METHODS

    cmds = [
        ("info", ["info", "{in}"]),
        ("info_json", ["info", "--json", "{in}"]),
        ("convert", ["convert", "{in}", "{out}.off"]),
        ("noise", ["noise", "{in}", "{out}.ply", "--sigma", "0.2"]),
        ("noise_normals", ["noise", "{in}", "{out}.obj", "--sigma", "0.2", "--along-normals"]),
        ("stats", ["stats", "{in}", "--sources", "3"]),
        ("stats_knn0", ["stats", "{in}", "--knn", "0"]),
        ("hash", ["hash", "{in}"]),
        ("hash_thesis", ["hash", "{in}", "--method", "thesis"]),
        ("hash_compare", ["hash", "--compare", "{in}", "{in}"]),
        ("compress", ["compress", "{in}", "{out}.jxm"]),
        ("roundtrip", ["compress", "{in}", "{out}.jxm", "&&", "decompress", "{out}.jxm", "{out}2.ply"]),
        ("denoise_auto", ["denoise", "{in}", "{out}.ply"]),
        ("denoise_auto_sigma", ["denoise", "{in}", "{out}.ply", "--noise-sigma", "0.01"]),
        ("denoise_lam_auto", ["denoise", "{in}", "{out}.ply", "--method", "kernel", "--lam", "auto"]),
        ("denoise_tune_sigma", ["denoise", "{in}", "{out}.ply", "--method", "taubin", "--tune", "--noise-sigma",
                                "0.01"]),
        ("denoise_lam_negative", ["denoise", "{in}", "{out}.ply", "--method", "kernel", "--lam", "-1"]),
        ("denoise_mu_positive", ["denoise", "{in}", "{out}.ply", "--method", "taubin", "--mu", "0.5"]),
    ]
    cmds += [(f"denoise_{m}", ["denoise", "{in}", "{out}.ply", "--method", m, "--iterations", "2"])
             for m in METHODS]
    return cmds


def setup():
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxmesh

    tmp = Path(tempfile.mkdtemp(prefix="jaxmesh-fuzz-cli-"))
    atexit.register(shutil.rmtree, tmp, ignore_errors=True)
    paths = {}
    for name, (v, f) in MESHES.items():
        p = tmp / f"{name}.obj"
        jaxmesh.save(jaxmesh.Mesh.from_arrays(np.asarray(v, float), np.asarray(f), warn=False), p)
        paths[name] = p
    return {"tmp": tmp, "paths": paths, "commands": _commands()}


def case_count(state) -> int:
    return len(state["paths"]) * len(state["commands"])


def _run(argv):
    from jaxmesh.cli import main

    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        code = main(argv)
    return code, err.getvalue()


def case(state, i: int):
    import jaxmesh

    names = sorted(state["paths"])
    mesh_name = names[i % len(names)]
    cmd_name, template = state["commands"][(i // len(names)) % len(state["commands"])]
    work = Path(tempfile.mkdtemp(dir=state["tmp"]))
    stem = str(work / "out")
    argv = [a.replace("{in}", str(state["paths"][mesh_name])).replace("{out}", stem) for a in template]
    label = f"{mesh_name} {cmd_name}"
    runs = [[]]
    for a in argv:
        if a == "&&":
            runs.append([])
        else:
            runs[-1].append(a)
    for run in runs:
        try:
            code, err = _run(run)
        except MemoryError:
            raise
        except BaseException as e:  # noqa: BLE001 - SystemExit from argparse, or a real traceback
            if isinstance(e, SystemExit) and e.code == 2:
                return label, ("error", "usage error")
            return label, ("traceback", f"{type(e).__name__}: {e}")
        lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("jaxmesh: warning:")]
        if code != 0:
            if code == 1 and len(lines) == 1 and lines[0].startswith("jaxmesh: error: "):
                return label, ("error", lines[0][16:])
            return label, ("traceback", f"exit {code}: {err[-300:]}")
    for out in work.glob("out*.*"):
        if out.suffix == ".jxm":
            continue
        try:
            m = jaxmesh.load(out)
        except Exception as e:  # noqa: BLE001
            return label, ("silent", f"{out.name} unreadable: {e}")
        if not np.isfinite(np.asarray(m.vertices)).all():
            return label, ("silent", f"{out.name} has non-finite coordinates")
    return label, "valid"

"""``jaxmesh hash`` (see :mod:`jaxmesh.cli`): print mesh hashes or compare two meshes.

    jaxmesh hash MESH [MESH ...] [--json] [--method robust|thesis]
    jaxmesh hash --compare A B [--json] [--method robust|thesis]

``--compare`` prints ρ and the verdict with the threshold used; the exit status
is 0 whatever the verdict (1 is kept for bad input).
"""

from __future__ import annotations

import argparse
import json

from .cli_denoise import CLIError, _mesh_source

__all__ = ["HASH"]


def _configure(p: argparse.ArgumentParser) -> None:
    from . import data

    p.add_argument("mesh", nargs="*", metavar="MESH", help="mesh file(s) to hash")
    p.add_argument("--sample", action="append", choices=sorted(data.SAMPLES),
                   help="hash a sample mesh shipped with jaxmesh (repeatable)")
    p.add_argument("--compare", nargs=2, metavar=("A", "B"),
                   help="compare two meshes: print ρ and the verdict")
    p.add_argument("--method", choices=("robust", "thesis"), default="robust",
                   help="robust: affine-normalised spherical-harmonic hash (default); "
                        "thesis: the thesis's METIS / MST / Laplace–Beltrami hash")
    p.add_argument("--parts", type=int, default=8, help="thesis hash: METIS parts (default 8)")
    p.add_argument("--eigenvalues", type=int, default=16,
                   help="thesis hash: eigenvalues per part, r (default 16)")
    p.add_argument("--json", action="store_true", help="one JSON object per line")


def _hasher(args):
    from .hash import mesh_hash, robust_hash

    if args.method == "thesis":
        if args.parts < 1 or args.eigenvalues < 1:
            raise CLIError("--parts and --eigenvalues must be >= 1")
        return lambda mesh: mesh_hash(mesh, parts=args.parts, r=args.eigenvalues)
    return robust_hash


def _run(args) -> int:
    import jax

    from .hash import THRESHOLDS, similarity, verdict
    from .io import load

    jax.config.update("jax_enable_x64", True)
    hasher = _hasher(args)
    if args.compare:
        if args.mesh or args.sample:
            raise CLIError("--compare takes exactly two meshes A B; do not name others")
        a, b = args.compare
        rho = similarity(hasher(load(a)), hasher(load(b)))
        same = verdict(rho, args.method)
        thr = THRESHOLDS[args.method]
        if args.json:
            print(json.dumps({"a": a, "b": b, "method": args.method, "rho": rho,
                              "threshold": thr, "same_model": same}))
        else:
            word = "same model" if same else "different models"
            print(f"rho {rho:.6f}  {word}  ({args.method} hash, threshold rho >= {thr})")
        return 0
    for label, loader in _mesh_source(args):
        h = hasher(loader())
        if args.json:
            print(json.dumps({"path": label, **h.to_dict()}), flush=True)
        else:
            vec = " ".join(f"{x:.6g}" for x in (h.log_vector if h.kind == "thesis" else h.vector))
            what = "log mu" if h.kind == "thesis" else "h"
            print(f"{label}  {h.kind}  {what}: {vec}", flush=True)
    return 0


HASH = ("print a mesh's hash, or compare two meshes (thesis ch.4)", _configure, _run)

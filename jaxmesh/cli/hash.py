"""``jaxmesh hash MESH ...`` prints hashes; ``jaxmesh hash --compare A B`` prints ρ
and the verdict with the threshold used (exit 0 whatever the verdict)."""

from __future__ import annotations

import json

import numpy as np

from ..hashing import THRESHOLDS, mesh_hash, robust_hash, similarity, verdict
from ..io import load
from ._common import CLIError, check_view, mesh_arguments, mesh_source, view_argument, write_view


def configure(p) -> None:
    mesh_arguments(p, "mesh file(s) to hash")
    p.add_argument("--compare", nargs=2, metavar=("A", "B"), help="compare two meshes: print ρ and the verdict")
    p.add_argument("--method", choices=("robust", "thesis"), default="robust",
                   help="robust: affine-normalised spherical-harmonic hash (default); "
                        "thesis: the thesis's METIS / MST / Laplace–Beltrami hash")
    p.add_argument("--parts", type=int, default=8, help="thesis hash: METIS parts (default 8)")
    p.add_argument("--eigenvalues", type=int, default=16, help="thesis hash: eigenvalues per part, r (default 16)")
    view_argument(p, "A and B of --compare, B coloured by its distance to A")
    p.add_argument("--force", action="store_true", help="replace the --view file if it exists")


def _hasher(args):
    if args.method == "thesis":
        if args.parts < 1 or args.eigenvalues < 1:
            raise CLIError("--parts and --eigenvalues must be >= 1")
        return lambda mesh: mesh_hash(mesh, parts=args.parts, r=args.eigenvalues)
    return robust_hash


def run(args) -> int:
    hasher = _hasher(args)
    if args.view and not args.compare:
        raise CLIError("--view shows the two meshes of --compare A B")
    if args.compare:
        if args.mesh or args.sample:
            raise CLIError("--compare takes exactly two meshes A B; do not name others")
        a, b = args.compare
        check_view(args)
        mesh_a, mesh_b = load(a), load(b)
        rho = similarity(hasher(mesh_a), hasher(mesh_b))
        same, thr = verdict(rho, args.method), THRESHOLDS[args.method]
        if args.json:
            print(json.dumps({"a": a, "b": b, "method": args.method, "rho": rho, "threshold": thr,
                              "same_model": same}))
        else:
            word = "same model" if same else "different models"
            print(f"rho {rho:.6f}  {word}  ({args.method} hash, threshold rho >= {thr})")
        if args.view:
            from ..view import vertex_distances

            write_view(args, [(a, mesh_a), (b, mesh_b)], [np.zeros(mesh_a.num_vertices), vertex_distances(mesh_a, mesh_b)],
                       scalar_label=f"distance to {a}")
        return 0
    for label, loader in mesh_source(args):
        h = hasher(loader())
        if args.json:
            print(json.dumps({"path": label, **h.to_dict()}), flush=True)
        else:
            vec = " ".join(f"{x:.6g}" for x in (h.log_vector if h.kind == "thesis" else h.vector))
            print(f"{label}  {h.kind}  {'log mu' if h.kind == 'thesis' else 'h'}: {vec}", flush=True)
    return 0

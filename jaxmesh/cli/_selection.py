"""``--pin`` and ``--region`` of ``jaxmesh denoise``: which vertices may move
(:mod:`jaxmesh.denoise.selection`)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ._common import CLIError

__all__ = ["selection_arguments", "selection_weights"]

_SPEC = ("'boundary', a text file of 0-based vertex indices (whitespace or comma separated), or the name of a "
         "vertex property of IN (PLY; non-zero values select)")


def selection_arguments(p) -> None:
    """--pin SPEC, --region SPEC (repeatable) and --transition N."""
    p.add_argument("--pin", action="append", metavar="SPEC",
                   help=f"keep these vertices exactly where they are: {_SPEC}; repeatable")
    p.add_argument("--region", action="append", metavar="SPEC",
                   help="denoise only these vertices (SPEC as for --pin), blending into the input over "
                        "--transition rings of edges around them; repeatable")
    p.add_argument("--transition", type=int, default=2, metavar="N",
                   help="--region: rings of edges over which the result blends into the input (default 2; 0: a "
                        "hard edge)")


def _indices_file(path: Path, num_vertices: int) -> np.ndarray:
    from ..denoise.selection import selection_mask

    tokens = path.read_text().replace(",", " ").split()
    try:
        indices = np.array([int(t) for t in tokens], np.int64)
    except ValueError as err:
        raise CLIError(f"{path}: expected vertex indices (integers), {err}") from None
    try:
        return selection_mask(num_vertices, indices)
    except ValueError as err:
        raise CLIError(f"{path}: {err}") from None


def _mask(spec: str, args, mesh) -> np.ndarray:
    from ..geodesics import boundary_vertices

    if spec == "boundary":
        mask = np.asarray(boundary_vertices(mesh))
        if not mask.any():
            print("jaxmesh: warning: the mesh has no boundary; 'boundary' selects no vertex", file=sys.stderr)
        return mask
    if Path(spec).is_file():
        return _indices_file(Path(spec), mesh.num_vertices)
    if args.input is None:
        raise CLIError(f"{spec}: no such file (and a sample mesh has no vertex properties)")
    from ..attributes import read_attributes, vertex_property

    try:
        attributes = read_attributes(args.input)
        if attributes is None:
            raise ValueError("the file has no vertex property besides its positions")
        return vertex_property(attributes, spec) != 0
    except ValueError as err:
        raise CLIError(f"{spec}: no such file, and not a vertex property of {args.input}: {err}") from None


def selection_weights(args, mesh):
    """The per-vertex weights of --pin/--region (None when neither is given)."""
    if not args.pin and not args.region:
        return None
    if args.transition < 0:
        raise CLIError(f"--transition must be >= 0, got {args.transition}")
    from ..denoise.selection import region_weights

    w = np.ones(mesh.num_vertices)
    if args.region:
        selected = np.any([_mask(s, args, mesh) for s in args.region], axis=0)
        w = np.asarray(region_weights(mesh, selected, args.transition), np.float64)
    if args.pin:
        w[np.any([_mask(s, args, mesh) for s in args.pin], axis=0)] = 0.0
    return w

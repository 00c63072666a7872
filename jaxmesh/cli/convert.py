"""``jaxmesh convert IN OUT``: between OBJ, PLY, OFF and STL, vertex order kept."""

from __future__ import annotations

import sys

from ..io import load, save
from ._common import input_attributes


def configure(p) -> None:
    p.add_argument("input", metavar="IN", help="mesh file to read")
    p.add_argument("output", metavar="OUT", help="mesh file to write (format from the suffix)")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    p.add_argument("--merge-duplicates", action="store_true",
                   help="merge exactly coincident vertices (first occurrence kept, order kept)")


def run(args) -> int:
    mesh = load(args.input, merge_duplicates=args.merge_duplicates or None)
    keep = None if args.merge_duplicates else input_attributes(args.input, args.output)
    save(mesh, args.output, overwrite=args.force, attributes=keep)
    print(f"wrote {args.output}: {mesh.num_vertices} vertices, {mesh.num_faces} faces", file=sys.stderr)
    return 0

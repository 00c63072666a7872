"""``jaxmesh info MESH ... [--json]``: counts, topology and geometry of each mesh."""

from __future__ import annotations

from ..topology import mesh_info
from ._common import mesh_arguments, mesh_source, print_record


def configure(p) -> None:
    mesh_arguments(p, "mesh file(s): OBJ, PLY, OFF, STL")


def run(args) -> int:
    for i, (label, loader) in enumerate(mesh_source(args)):
        print_record({"path": label, **mesh_info(loader())}, args.json, i == 0)
    return 0

"""``jaxmesh view MESH ... -o PAGE.html``: the meshes side by side in one
self-contained HTML page (:mod:`jaxmesh.view`): rotation shared by every panel,
flat or smooth shading, optional colouring by the distance to a reference."""

from __future__ import annotations

from .. import data
from ..io import load
from ..view import SHADINGS, vertex_distances, write_viewer
from ._common import CLIError, check_output, mesh_source


def configure(p) -> None:
    p.add_argument("mesh", nargs="*", metavar="MESH", help="mesh files to show, left to right")
    p.add_argument("--sample", action="append", choices=sorted(data.SAMPLES),
                   help="a sample mesh shipped with jaxmesh (repeatable; shown before the files)")
    p.add_argument("-o", "--output", required=True, metavar="HTML", help="the page to write")
    p.add_argument("--force", action="store_true", help="replace HTML if it exists")
    p.add_argument("--shading", choices=SHADINGS, default="flat", help="shading when the page opens "
                   "(default flat; the page has a switch)")
    p.add_argument("--color-by", choices=("none", "distance"), default="none",
                   help="distance: colour each mesh by the distance of its vertices to --reference "
                        "(or to the first mesh): to the same vertex where the vertex counts agree, "
                        "else to the closest point of the reference's surface")
    p.add_argument("--reference", metavar="MESH", help="the reference of --color-by distance")
    p.add_argument("--title", default="jaxmesh view", help="the page title")


def run(args) -> int:
    check_output(args.output, args.force)
    if args.reference and args.color_by != "distance":
        raise CLIError("--reference is the reference of --color-by distance; add --color-by distance")
    meshes = [(label, loader()) for label, loader in mesh_source(args)]
    for label, mesh in meshes:
        if mesh.batch_shape:
            raise CLIError(f"{label}: the viewer draws single meshes")
    scalars = None
    if args.color_by == "distance":
        reference = load(args.reference) if args.reference else meshes[0][1]
        scalars = [vertex_distances(reference, mesh) for _, mesh in meshes]
    write_viewer(args.output, meshes, scalars, overwrite=args.force, shading=args.shading, title=args.title,
                 scalar_label="distance to " + (args.reference or meshes[0][0]))
    print(f"{args.output}: {len(meshes)} mesh{'es' if len(meshes) > 1 else ''}")
    return 0

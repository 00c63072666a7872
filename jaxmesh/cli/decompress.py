"""``jaxmesh decompress IN.jxm OUT`` decodes; ``--info`` prints the validated header.
IN may be ``-`` (standard input)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ..compress import decompress, inspect
from ..io import MeshFileError, save
from ._common import CLIError, check_output


def configure(p) -> None:
    p.add_argument("input", metavar="IN", help="compressed mesh (.jxm; - for stdin)")
    p.add_argument("output", nargs="?", metavar="OUT", help="mesh file to write (OBJ, PLY, OFF, STL)")
    p.add_argument("--info", action="store_true", help="print the file's header instead of decoding it")
    p.add_argument("--json", action="store_true", help="--info as one JSON object")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")


def _read(name: str) -> bytes:
    if name == "-":
        return sys.stdin.buffer.read()
    p = Path(name)
    if not p.is_file():
        raise MeshFileError(f"{p}: no such file" if not p.exists() else f"{p}: not a regular file")
    return p.read_bytes()


def run(args) -> int:
    data = _read(args.input)
    if not args.info and not args.output:
        raise CLIError("no output file: name OUT (or use --info)")
    try:
        if args.info:
            info = inspect(data)
            print(json.dumps({"path": args.input, **info}) if args.json else
                  "\n".join([args.input] + [f"  {k.replace('_', ' ')}: {v}" for k, v in info.items()]))
            return 0
        check_output(args.output, args.force, mesh=True)
        mesh = decompress(data)
    except ValueError as err:
        raise err if isinstance(err, CLIError) else CLIError(f"{args.input}: {err}") from err
    save(mesh, args.output, overwrite=args.force)
    print(f"{args.input} -> {args.output}: {mesh.num_vertices} vertices, {mesh.num_faces} faces")
    return 0

"""What every command shares: the error type, input/output arguments and checks,
the per-mesh record printer, and the capture of blind-tuning caveats."""

from __future__ import annotations

import argparse
import json
import os
import sys
import warnings
from pathlib import Path
from collections.abc import Callable

from .. import data

__all__ = ["CLIError", "io_arguments", "mesh_arguments", "load_input", "input_attributes", "mesh_source",
           "check_output", "positional_output", "names_a_mesh_format", "print_record", "with_caveats",
           "view_argument", "check_view", "write_view"]


class CLIError(ValueError):
    """Reported by :func:`jaxmesh.cli.main` as ``jaxmesh: error: ...`` (exit 1)."""


def io_arguments(p: argparse.ArgumentParser) -> None:
    """IN, OUT, --sample NAME, --force."""
    p.add_argument("input", nargs="?", metavar="IN", help="mesh file to read (or use --sample)")
    p.add_argument("output", nargs="?", metavar="OUT", help="mesh file to write (format from the suffix)")
    p.add_argument("--sample", choices=sorted(data.SAMPLES), help="read a sample mesh shipped with jaxmesh")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")


def mesh_arguments(p: argparse.ArgumentParser, what: str = "mesh file(s)") -> None:
    """MESH ..., --sample NAME (repeatable), --json."""
    p.add_argument("mesh", nargs="*", metavar="MESH", help=what)
    p.add_argument("--sample", action="append", choices=sorted(data.SAMPLES),
                   help="a sample mesh shipped with jaxmesh (repeatable)")
    p.add_argument("--json", action="store_true", help="one JSON object per mesh, per line")


def load_input(args):
    """(label, mesh) named by IN or --sample (float64: the CLI runs with x64)."""
    if args.sample and args.input:
        raise CLIError("give either IN or --sample, not both")
    if args.sample:
        return f"sample:{args.sample}", data.load_sample(args.sample, dtype="float64")
    if not args.input:
        raise CLIError("no input mesh: name IN or use --sample NAME")
    from ..io import load
    from ..transforms import far_vertices

    mesh = load(args.input)
    far = far_vertices(mesh)
    if far.size:
        at = [float(c) for c in mesh.vertices[int(far[0])]]
        print(f"jaxmesh: warning: {args.input}: {far.size} vertex(es) lie more than 1e4 times the typical distance "
              f"from the rest (vertex {int(far[0])} at {at}: a corrupt coordinate?); the working frame leaves "
              "them out, but a denoiser spreads them over their neighbours and a codec's quantization erases the "
              "rest: remove them first", file=sys.stderr)
    return args.input, mesh


def input_attributes(source: str | None, out: str):
    """What the file ``source`` carries besides positions and triangles, to keep in ``out``
    (:func:`jaxmesh.read_attributes`), or None: nothing to keep, no file (a sample), or ``out``'s
    format cannot hold it, which a ``jaxmesh: warning:`` line says."""
    if source is None:
        return None
    from ..attributes import read_attributes

    try:
        attributes = read_attributes(source)
    except (OSError, ValueError) as err:
        print(f"jaxmesh: warning: {source}: only positions and triangles are written to {out} ({err})",
              file=sys.stderr)
        return None
    if attributes is None:
        return None
    fmt = Path(out).suffix.lstrip(".").lower()
    if fmt != attributes.format:
        print(f"jaxmesh: warning: {source} carries {', '.join(attributes.kinds)}; {out} is {fmt.upper()}, which "
              f"cannot hold them, so only positions and triangles are written (write .{attributes.format} to keep "
              "them)", file=sys.stderr)
        return None
    return attributes


def mesh_source(args) -> list[tuple[str, Callable]]:
    """(label, loader) for each mesh named by MESH arguments or --sample."""
    out = [(f"sample:{n}", lambda n=n: data.load_sample(n, dtype="float64")) for n in args.sample or []]
    from ..io import load

    out += [(path, lambda path=path: load(path)) for path in args.mesh or []]
    if not out:
        raise CLIError("no mesh given: name a MESH file or --sample NAME "
                       f"(samples: {', '.join(sorted(data.SAMPLES))})")
    return out


def check_output(path: str, force: bool, mesh: bool = False) -> None:
    """Refuse, before any work, an output that could not be written: a directory, an existing file
    (unless ``force``), a missing or unwritable folder, or (``mesh``) a suffix no mesh writer knows."""
    p = Path(path)
    if p.is_dir():
        raise CLIError(f"{path} is a directory; name the file to write")
    if p.is_symlink() and not p.exists() and not force:
        raise CLIError(f"{path} is a symbolic link to {os.readlink(p)}, which does not exist; use --force to "
                       "replace the link with the file")
    if p.exists() and not force:
        raise CLIError(f"{path} exists; use --force to replace it")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise CLIError(f"{path}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise CLIError(f"{path}: directory {parent} is not writable")
    if mesh and not names_a_mesh_format(path):
        from ..io import SUPPORTED_FORMATS

        raise CLIError(f"{path}: unsupported mesh format {p.suffix or '(no suffix)'}; name OUT with one of "
                       + ", ".join("." + f for f in SUPPORTED_FORMATS))


def names_a_mesh_format(path: str) -> bool:
    """Whether ``path``'s suffix is one of the mesh formats :func:`jaxmesh.save` writes."""
    from ..io import SUPPORTED_FORMATS

    return Path(path).suffix.lstrip(".").lower() in SUPPORTED_FORMATS


def positional_output(args) -> str:
    """OUT (with --sample the single positional argument is OUT)."""
    if args.sample and args.input and not args.output:
        args.output, args.input = args.input, None
    if not args.output:
        raise CLIError("no output file: name OUT")
    return args.output


def _format_value(v) -> str:
    if isinstance(v, bool):
        return "yes" if v else "no"
    if v is None:
        return "undefined"
    return f"{v:.6g}" if isinstance(v, float) else str(v)


def print_record(record: dict, as_json: bool, first: bool) -> None:
    """One mesh's record: a JSON line, or a labelled block (blank line between meshes)."""
    if as_json:
        print(json.dumps(record), flush=True)
        return
    if not first:
        print()
    print(record["path"])
    width = max(len(k) for k in record)
    for key, value in record.items():
        if key != "path":
            print(f"  {key.replace('_', ' '):<{width}}  {_format_value(value)}")


def with_caveats(fn, *args, **kwargs):
    """(fn(...), caveats): warnings raised inside are printed as ``jaxmesh: warning:``
    lines; the blind-tuning ones are also returned for the JSON report."""
    from ..tune import BlindTuningWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = fn(*args, **kwargs)
    for w in caught:
        print(f"jaxmesh: warning: {w.message}", file=sys.stderr)
    return out, [str(w.message) for w in caught if issubclass(w.category, BlindTuningWarning)]


def view_argument(p: argparse.ArgumentParser, what: str) -> None:
    """--view HTML: a self-contained viewer page of ``what`` (:mod:`jaxmesh.view`)."""
    p.add_argument("--view", metavar="HTML", help=f"also write a viewer page (one HTML file) of {what}")


def check_view(args) -> None:
    """Refuse an existing --view file before any work is done (unless --force)."""
    if getattr(args, "view", None):
        check_output(args.view, getattr(args, "force", False))


def write_view(args, meshes, scalars=None, scalar_label: str = "distance") -> None:
    """Write the --view page of ``meshes`` ((label, mesh) pairs), if one was asked for."""
    if not getattr(args, "view", None):
        return
    from ..view import write_viewer

    title = "jaxmesh " + args.command if getattr(args, "command", None) else "jaxmesh view"
    write_viewer(args.view, meshes, scalars, overwrite=getattr(args, "force", False), title=title,
                 scalar_label=scalar_label)
    print(f"jaxmesh: wrote viewer page {args.view}", file=sys.stderr)

"""``jaxmesh denoise IN OUT``: any registered method, or ``--method auto`` (the
default: method and parameters chosen blind); ``--lam auto`` / ``--tune`` tune;
``--out-dir DIR IN ...``: a whole dataset (:mod:`._dataset`)."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import time

from ..denoise import as_method, hold
from ..io import load, save
from ..tune import choose_denoiser, denoise_with_tuning
from ..tune.auto import NOISE_MODELS
from ..tune.patches import PATCH_COUNT, PATCH_FACTOR, SEARCH_VERTICES
from .. import data
from ._common import (CLIError, check_output, check_view, input_attributes, load_input, positional_output,
                      view_argument, with_caveats, write_view)
from ._dataset import dataset_arguments, run_dataset
from ._denoise_report import progress_bar, report_auto, report_run
from ._flags import add_parameter_flags, given_parameters, list_methods
from ._selection import selection_arguments, selection_weights


def configure(p) -> None:
    p.add_argument("paths", nargs="*", metavar="IN OUT", help="mesh to read and mesh to write (with --out-dir: "
                   "every input)")
    p.add_argument("--sample", choices=sorted(data.SAMPLES), help="read a sample mesh shipped with jaxmesh")
    p.add_argument("--force", action="store_true", help="replace OUT if it exists")
    dataset_arguments(p)
    p.add_argument("--method", default="auto",
                   help="denoising method, or 'auto' (default): choose the method and its parameters "
                        "blind, by a recorrupted estimate of the normal error (see --list-methods)")
    p.add_argument("--list-methods", action="store_true", help="list methods and their parameters, then exit")
    add_parameter_flags(p)
    p.add_argument("--reference", metavar="CLEAN",
                   help="clean mesh (same connectivity): print the errors; with --out-dir, a folder of clean "
                        "meshes named like the inputs (errors per mesh in --report; training set of --tune-on)")
    p.add_argument("--raw-units", action="store_true",
                   help="run in the file's units (default: scaled to a unit bounding-box diagonal and "
                        "back, so that kernel λ means the same for every mesh)")
    p.add_argument("--tune", action="store_true",
                   help="tune every continuous parameter of the method (as if each were 'auto')")
    p.add_argument("--noise-sigma", type=float, metavar="S",
                   help="noise standard deviation in the file's units, for blind tuning (default: estimated; "
                        "between 1e-7 and 1e3 mean edge lengths)")
    p.add_argument("--noise-model", choices=NOISE_MODELS, default=None,
                   help="--method auto: the noise law of the recorrupted estimate: 'normal' (Gaussian along "
                        "the normals), 'isotropic' (Gaussian), 'impulsive' (a fraction of the vertices displaced "
                        "along their normals), or 'auto' (default: impulsive if the mesh reads so, else Gaussian "
                        "with the noise within the surface estimated)")
    p.add_argument("--search-vertices", type=_search_vertices, default=SEARCH_VERTICES, metavar="N",
                   help=f"--method auto: on a mesh of more than {PATCH_FACTOR:g}N vertices, rank the candidates on "
                        f"patches holding about N vertices and run the choice on the whole mesh (default "
                        f"{SEARCH_VERTICES}); 'all': rank on the whole mesh")
    p.add_argument("--search-ladder", type=_search_ladder, default=None, metavar="R",
                   help="--method auto: rank on the search mesh padded to a ladder of sizes R apart (e.g. 1.19), "
                        "so that meshes of one rung share the compiled search; the same choice (default: off, "
                        "measured faster on varied meshes)")
    selection_arguments(p)
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    view_argument(p, "the input and the result (and --reference, colouring both by the distance to it)")
    p.epilog = ("Method parameters are flags named after them (--lam, --iterations, --mu, ...). "
                "A continuous parameter given as 'auto' (e.g. --lam auto) is tuned: against "
                "--reference if given (supervised), else blind (Stein's unbiased risk estimate "
                "of the visual error, noise from --noise-sigma or estimated).")


def _search_vertices(text: str) -> int | None:
    """--search-vertices: an int >= PATCH_COUNT, or 'all' (None: the whole mesh)."""
    if text == "all":
        return None
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < PATCH_COUNT:
        raise argparse.ArgumentTypeError(f"expected an integer >= {PATCH_COUNT} or 'all', got {text!r}")
    return value


def _search_ladder(text: str) -> float:
    """--search-ladder: a finite number > 1."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 1 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number > 1 (the ratio between padded sizes), got {text!r}")
    return value


def _load_pair(args):
    """(label, mesh, reference or None, output path); the reference must share the connectivity."""
    out = positional_output(args)
    label, mesh = load_input(args)
    check_output(out, args.force, mesh=True)
    check_view(args)
    reference = load(args.reference) if args.reference else None
    if reference is not None and not mesh.same_connectivity(reference):
        raise CLIError(f"--reference {args.reference} does not have the connectivity of {label}")
    return label, mesh, reference, out


def _view(args, label, mesh, out, result, reference) -> None:
    """--view: the input, the result and the reference, coloured by the distance to it."""
    from ..view import vertex_distances

    pairs = [(label, mesh), (out, result)] + ([(args.reference, reference)] if reference is not None else [])
    scalars = None if reference is None else [vertex_distances(reference, mesh), vertex_distances(reference, result),
                                              None]
    write_view(args, pairs, scalars, scalar_label=f"distance to {args.reference}")


def run(args) -> int:
    if args.list_methods:
        return list_methods()
    given = given_parameters(args)
    if args.noise_sigma is not None and not args.noise_sigma > 0:
        raise CLIError(f"--noise-sigma must be > 0, got {args.noise_sigma}")
    if args.out_dir is not None:
        if args.pin or args.region:
            raise CLIError("--pin and --region select vertices of one mesh; they do not combine with --out-dir")
        if args.view:
            raise CLIError("--view shows one input and its result; it does not combine with --out-dir")
        return run_dataset(args, given)
    if len(args.paths) > 2:
        raise CLIError(f"{len(args.paths)} paths given: name IN OUT (or --out-dir DIR for many inputs)")
    args.input, args.output = (args.paths + [None, None])[:2]
    if args.method == "auto" and (given or args.tune):
        flags = ", ".join("--" + k.replace("_", "-") for k in sorted(given)) or "--tune"
        raise CLIError(f"{flags} needs a named method (--method NAME); --method auto chooses its own parameters")
    if args.method == "auto":
        label, mesh, reference, out = _load_pair(args)
        keep, where = input_attributes(args.input, out), selection_weights(args, mesh)
        start = time.perf_counter()
        choice, caveats = with_caveats(choose_denoiser, mesh, sigma=args.noise_sigma,
                                       noise_model=args.noise_model or "auto", search_vertices=args.search_vertices,
                                       ladder=args.search_ladder)
        if where is not None:
            choice = dataclasses.replace(choice, mesh=hold(mesh, choice.mesh, where))
        save(choice.mesh, out, overwrite=args.force, attributes=keep)
        _view(args, label, mesh, out, choice.mesh, reference)
        return report_auto(args, label, out, mesh, reference, choice, caveats, time.perf_counter() - start)
    if args.noise_model is not None:
        raise CLIError("--noise-model applies to --method auto (the blind choice); drop it or the named method")
    for flag, given_ in (("--search-vertices", args.search_vertices != SEARCH_VERTICES),
                         ("--search-ladder", args.search_ladder is not None)):
        if given_:
            raise CLIError(f"{flag} applies to --method auto (the blind choice); drop it or the named method")
    if args.raw_units and (args.tune or "auto" in given.values()):
        raise CLIError("tuning runs in the unit-diagonal frame; drop --raw-units")
    label, mesh, reference, out = _load_pair(args)
    keep, where = input_attributes(args.input, out), selection_weights(args, mesh)
    start = time.perf_counter()
    tuning = args.tune or "auto" in given.values()
    total = given.get("iterations", as_method(args.method).defaults().get("iterations", 1))
    with progress_bar(args.method, total, mesh.num_vertices) if not tuning else contextlib.nullcontext():
        result, caveats = with_caveats(denoise_with_tuning, mesh, args.method, given, tune_all=args.tune,
                                       reference=reference, sigma=args.noise_sigma, unit_frame=not args.raw_units)
    if where is not None:
        result = dataclasses.replace(result, mesh=hold(mesh, result.mesh, where))
    save(result.mesh, out, overwrite=args.force, attributes=keep)
    _view(args, label, mesh, out, result.mesh, reference)
    return report_run(args, label, out, mesh, reference, result, caveats, time.perf_counter() - start)

"""``jaxmesh noise IN OUT --sigma S [--model impulsive --fraction P]``: the noise models of
:mod:`jaxmesh.noise` (Gaussian, thesis ch.2 eq.1; impulsive)."""

from __future__ import annotations

import math
import sys

from ..io import save
from ..noise import IMPULSIVE_FRACTION, add_noise
from ._common import CLIError, check_output, input_attributes, io_arguments, load_input, positional_output

#: --model's choices
MODELS = ("gaussian", "impulsive")


def configure(p) -> None:
    io_arguments(p)
    p.add_argument("--sigma", type=float, default=0.1,
                   help="noise standard deviation, in mean edge lengths (default 0.1)")
    p.add_argument("--absolute", action="store_true", help="--sigma is in the mesh's own units")
    p.add_argument("--model", choices=MODELS, default="gaussian",
                   help="gaussian: every vertex (default); impulsive: a random fraction of the vertices, "
                        "along their normals, the rest untouched")
    p.add_argument("--fraction", type=float, default=None, metavar="P",
                   help=f"with --model impulsive: the probability that a vertex is displaced "
                        f"(default {IMPULSIVE_FRACTION})")
    p.add_argument("--along-normals", action="store_true", help="displace along vertex normals only")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def run(args) -> int:
    out = positional_output(args)
    if not (math.isfinite(args.sigma) and args.sigma >= 0):
        raise CLIError(f"--sigma must be a finite number >= 0, got {args.sigma}")
    if args.fraction is not None and args.model != "impulsive":
        raise CLIError("--fraction applies to --model impulsive only")
    fraction = IMPULSIVE_FRACTION if args.fraction is None else args.fraction
    if args.model == "impulsive" and not 0 <= fraction <= 1:
        raise CLIError(f"--fraction must be in [0, 1], got {args.fraction}")
    label, mesh = load_input(args)
    check_output(out, args.force, mesh=True)
    keep = input_attributes(args.input, out)
    impulsive = args.model == "impulsive"
    noisy = add_noise(mesh, args.sigma, args.seed, along_normals=args.along_normals or impulsive,
                      relative=not args.absolute, fraction=fraction if impulsive else 1.0)
    save(noisy, out, overwrite=args.force, attributes=keep)
    unit = "" if args.absolute else " mean edge lengths"
    what = f"impulsive noise (fraction {fraction:g}) sigma" if impulsive else "Gaussian noise sigma"
    print(f"jaxmesh: wrote {out}: {label} + {what}={args.sigma:g}{unit}, seed {args.seed}", file=sys.stderr)
    return 0

"""The registry's parameters as command-line flags (``--lam``, ``--iterations``, ...)
and ``--list-methods``: parameters as data drive the CLI."""

from __future__ import annotations

import argparse

from ..denoise import METHODS
from ..tune import AUTO


def _bool(text: str) -> bool:
    t = text.lower()
    if t in ("1", "true", "yes", "on"):
        return True
    if t in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"expected yes/no, got {text!r}")


def _float_or_auto(text: str):
    if text == AUTO:
        return AUTO
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or {AUTO!r}, got {text!r}") from None


def add_parameter_flags(p: argparse.ArgumentParser) -> None:
    """One hidden flag per parameter name over every registered method (dest ``p_NAME``)."""
    seen = set()
    for method in METHODS.values():
        for name, param in method.params.items():
            if param.kind == "aux" or name in seen:
                continue
            seen.add(name)
            kind = {"int": int, "continuous": _float_or_auto}.get(param.kind)
            if kind is None:
                kind = _bool if isinstance(param.default, bool) else str
            p.add_argument("--" + name.replace("_", "-"), dest="p_" + name, type=kind, default=None,
                           metavar=name.upper(), help=argparse.SUPPRESS)


def given_parameters(args) -> dict:
    return {k[2:]: v for k, v in vars(args).items() if k.startswith("p_") and v is not None}


def list_methods() -> int:
    print(f"{AUTO}: choose the method and its parameters blind (default) [jaxmesh.tune.choose_denoiser]")
    for name, m in METHODS.items():
        packs = " (packed into disjoint unions by --out-dir)" if m.packable else ""
        print(f"{name}: {m.summary} [{m.reference}]{packs}")
        for pname, p in m.params.items():
            if p.kind != "aux":
                print(f"    --{pname.replace('_', '-'):<18} {p.default!s:<12} {p.help}")
    return 0

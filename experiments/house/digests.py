"""SHA-256 digests of what the library computes, to show that a refactoring left
behaviour unchanged: run it before and after, and compare the two outputs.

    .venv/bin/python experiments/house/digests.py [--meshes cow fandisk] > digests.txt

One line per result: every registry method at its defaults (float64, in the
unit frame as ``jaxmesh denoise --method NAME`` runs it), the blind chooser
(``choose_denoiser`` at its defaults), the codec's bitstream (``compress``), the
thesis and robust hashes, and ``mesh_statistics``, on each mesh given (from
../shared/meshes).  A digest covers the exact bytes (positions, the file, the
hash vector, the statistics' JSON with every float written by ``repr``), so
any change, however small, shows.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import warnings
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402

import jaxmesh  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from shared_meshes import load  # noqa: E402


def digest(data) -> str:
    """The first 16 hex digits of the SHA-256 of bytes, an array's bytes or a JSON value."""
    if isinstance(data, (bytes, bytearray)):
        raw = bytes(data)
    elif isinstance(data, (dict, list)):
        raw = json.dumps(data, sort_keys=True, default=repr).encode()
    else:
        raw = np.ascontiguousarray(np.asarray(data)).tobytes()
    return hashlib.sha256(raw).hexdigest()[:16]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="+", default=["cow", "fandisk"])
    args = ap.parse_args()
    from jaxmesh.compress import compress
    from jaxmesh.denoise import METHODS, denoise_in_unit_frame
    from jaxmesh.hashing import mesh_hash, robust_hash
    from jaxmesh.stats import mesh_statistics
    from jaxmesh.tune import choose_denoiser

    warnings.simplefilter("ignore")
    for name in args.meshes:
        clean = load(name)
        noisy = jaxmesh.add_noise(clean, 0.3 * float(jaxmesh.mean_edge_length(clean)), 0)
        for method in sorted(METHODS):
            print(f"{name} denoise {method} {digest(denoise_in_unit_frame(noisy, method).vertices)}", flush=True)
        choice = choose_denoiser(noisy)
        print(f"{name} choose_denoiser {choice.method} {digest(choice.mesh.vertices)}", flush=True)
        print(f"{name} compress {digest(compress(clean).data)}", flush=True)
        print(f"{name} mesh_hash {digest(mesh_hash(clean).vector)}", flush=True)
        print(f"{name} robust_hash {digest(robust_hash(clean).vector)}", flush=True)
        print(f"{name} mesh_statistics {digest(mesh_statistics(clean))}", flush=True)


if __name__ == "__main__":
    main()

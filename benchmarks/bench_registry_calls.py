"""Eager calls of the denoisers: first and second call in a fresh process.

    .venv/bin/python benchmarks/bench_registry_calls.py [--sample bunny] [--methods kernel taubin ...]

For each method, a fresh Python process (no compiled program cached, no persistent
compilation cache) calls ``METHODS[name](mesh)`` twice on the noisy sample (σ = 0.3ℓ̄,
unit diagonal, float64), then ``denoise_in_unit_frame(mesh, name)`` twice, and reports
the four wall times.  A second call shows what a kept program saves: a call that traced
and compiled its iteration loop again costs about as much as the first.  Not part of the
test suite: compare the rows of one run.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys

CHILD = r"""
import json, sys, time
import jax
jax.config.update("jax_enable_x64", True)
import jaxmesh
from jaxmesh.data import load_sample
from jaxmesh.denoise import METHODS, denoise_in_unit_frame
name, sample = sys.argv[1:3]
mesh = jaxmesh.add_noise(jaxmesh.normalize(load_sample(sample, dtype="float64")), 0.3, 0)
out = {}
for how, call in (("registry", lambda: METHODS[name](mesh)), ("framed", lambda: denoise_in_unit_frame(mesh, name))):
    for i in (1, 2):
        t = time.perf_counter()
        jax.block_until_ready(call().vertices)
        out[f"{how}_{i}"] = time.perf_counter() - t
print(json.dumps(out))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sample", default="bunny")
    ap.add_argument("--methods", nargs="+", default=["kernel", "taubin", "bilateral_normal", "guided_normal"])
    args = ap.parse_args()
    print(f"{args.sample}, float64, each method in a fresh process, seconds\n")
    print("| method | registry call 1 | call 2 | denoise_in_unit_frame call 1 | call 2 |")
    print("|---|---|---|---|---|")
    for name in args.methods:
        r = subprocess.run([sys.executable, "-W", "ignore", "-c", CHILD, name, args.sample],
                           capture_output=True, text=True)
        if r.returncode:
            raise SystemExit(r.stderr)
        t = json.loads(r.stdout.strip().splitlines()[-1])
        print(f"| {name} | {t['registry_1']:.2f} | {t['registry_2']:.2f} | {t['framed_1']:.2f} | {t['framed_2']:.2f} |")


if __name__ == "__main__":
    main()

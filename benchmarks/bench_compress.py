"""Codec speed and peak memory against Draco in the same run.

    .venv/bin/python benchmarks/bench_compress.py [--meshes bunny big] [--keep 0.05] [--bits 10] [--qp 8]

For each mesh, each codec runs in a fresh child process (so its peak resident
memory, ``ru_maxrss``, is its own): read the mesh, encode, decode.  Reported:
encode and decode wall time, file size, peak memory, and the ratios
jaxmesh / Draco.  ``big`` is igea (134k vertices) refined once by 1-to-4
midpoint subdivision: 537k vertices, 1.07M faces.  Draco (DracoPy, compression
level 10) at ``--qp`` 8 gives a surface RMS of the same order as the jaxmesh
setting (see experiments/compress/rate_distortion.md).  Needs ../shared/meshes.
Not part of the test suite.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "meshes"

CHILD = r"""
import json, resource, sys, time
import jax
jax.config.update("jax_enable_x64", True)
import numpy as np, trimesh
import jaxmesh
name, codec, keep, bits, qp, shared = sys.argv[1:7]
keep, bits, qp = float(keep), int(bits), int(qp)
src = "igea" if name == "big" else name
tm = trimesh.load(f"{shared}/{src}.ply", process=False)
v, f = np.asarray(tm.vertices, np.float64), np.asarray(tm.faces)
if name == "big":
    v, f = trimesh.remesh.subdivide(v, f)
mesh = jaxmesh.Mesh.from_arrays(v, f, warn=False)
out = {"mesh": name, "codec": codec, "vertices": len(v)}
if codec == "jaxmesh":
    t = time.perf_counter(); c = jaxmesh.compress.compress(mesh, keep=keep, bits=bits); out["encode_s"] = time.perf_counter() - t
    data = c.data
    t = time.perf_counter(); d = jaxmesh.compress.decompress(data); out["decode_s"] = time.perf_counter() - t
    out["connectivity_bpv"] = c.stats["section_bits_per_vertex"]["connectivity"]
else:
    import DracoPy
    t = time.perf_counter(); data = DracoPy.encode(v, f, quantization_bits=qp, compression_level=10); out["encode_s"] = time.perf_counter() - t
    t = time.perf_counter(); d = DracoPy.decode(data); out["decode_s"] = time.perf_counter() - t
out["bpv"] = 8 * len(data) / len(v)
out["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(out))
"""


def run(name: str, codec: str, args) -> dict:
    r = subprocess.run([sys.executable, "-c", CHILD, name, codec, str(args.keep), str(args.bits), str(args.qp),
                        str(SHARED)], capture_output=True, text=True, cwd=ROOT)
    if r.returncode:
        raise SystemExit(r.stderr)
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--meshes", nargs="+", default=["bunny", "big"])
    ap.add_argument("--keep", type=float, default=0.05)
    ap.add_argument("--bits", type=int, default=10)
    ap.add_argument("--qp", type=int, default=8)
    args = ap.parse_args()
    if not SHARED.is_dir():
        raise SystemExit(f"{SHARED} not found: this benchmark needs ../shared/meshes")
    print(f"jaxmesh keep {args.keep} bits {args.bits} vs Draco qp {args.qp} (level 10); one run each, 2 CPU cores")
    print("| mesh | vertices | codec | encode s | decode s | bits/vertex | peak RSS MB |")
    print("|---|---|---|---|---|---|---|")
    for name in args.meshes:
        res = {c: run(name, c, args) for c in ("jaxmesh", "draco")}
        for c, r in res.items():
            print(f"| {name} | {r['vertices']} | {c} | {r['encode_s']:.2f} | {r['decode_s']:.2f} | {r['bpv']:.2f} | "
                  f"{r['peak_rss_mb']:.0f} |", flush=True)
        j, d = res["jaxmesh"], res["draco"]
        print(f"| {name} | | ratio jaxmesh/Draco | {j['encode_s'] / d['encode_s']:.0f}x | "
              f"{j['decode_s'] / max(d['decode_s'], 1e-9):.0f}x | {j['bpv'] / d['bpv']:.2f} | "
              f"{j['peak_rss_mb'] / d['peak_rss_mb']:.1f} |", flush=True)


if __name__ == "__main__":
    main()

"""The blind chooser with and without racing, in one process: the seconds of a
warm ``choose_denoiser`` call (every program already compiled) and whether the
choice is the same.

    .venv/bin/python benchmarks/bench_race.py [--meshes bunny fandisk] [--sigma 0.3]

``race_keep=None`` runs every setting on every recorruption; the default,
:data:`jaxmesh.tune.RACE_KEEP`, runs every setting on the first and only the
best of each family on the others.  float64 under the ``jaxmesh`` command's XLA
flag (:mod:`jaxmesh.compiler`); the noisy mesh is the shared mesh in its unit
frame with Gaussian noise of σ mean edge lengths (seed 0).  Each variant is
called twice and the second call timed; the default runs first, and its first call's
compiles (count and XLA's compile seconds) are reported.  Needs ../shared/meshes.  Compare the
ratio: seconds move with the machine's load.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from jaxmesh.compiler import prefer_fast_cpu_compiles

prefer_fast_cpu_compiles()

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import jaxmesh  # noqa: E402
from jaxmesh.tune import RACE_KEEP, choose_denoiser  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))
from shared_meshes import load as load_shared  # noqa: E402


COMPILES = {"count": 0, "seconds": 0.0}


def _on_event(event, duration, **kwargs):
    if event == "/jax/core/compile/backend_compile_duration":
        COMPILES["count"] += 1
        COMPILES["seconds"] += duration


def warm_call(noisy, race_keep):
    """(seconds of a second call, the first call's (compiles, seconds compiling), the result)."""
    before = dict(COMPILES)
    choose_denoiser(noisy, race_keep=race_keep)
    first = (COMPILES["count"] - before["count"], COMPILES["seconds"] - before["seconds"])
    start = time.perf_counter()
    c = choose_denoiser(noisy, race_keep=race_keep)
    jax.block_until_ready(c.mesh.vertices)
    return time.perf_counter() - start, first, c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", nargs="*", default=["bunny", "fandisk"])
    ap.add_argument("--sigma", type=float, default=0.3, help="noise, in mean edge lengths")
    args = ap.parse_args()
    jax.monitoring.register_event_duration_secs_listener(_on_event)
    print(f"| mesh | ranked on V | every setting on every draw, s | raced (keep {RACE_KEEP}), s | ratio "
          "| same choice | the default's first call: programs compiled, s compiling |")
    print("|---|---|---|---|---|---|---|")
    for name in args.meshes:
        noisy = jaxmesh.add_noise(jaxmesh.normalize(load_shared(name)), args.sigma, jax.random.PRNGKey(0))
        t_race, first, raced = warm_call(noisy, RACE_KEEP)       # the default first: its compiles are its own
        t_all, _, full = warm_call(noisy, None)
        same = [c[:2] for c in full.components] == [c[:2] for c in raced.components]
        print(f"| {name} | {raced.search_vertices} | {t_all:.2f} | {t_race:.2f} | {t_all / t_race:.2f} | "
              f"{'yes' if same else 'no'} | {first[0]}, {first[1]:.2f} |", flush=True)


if __name__ == "__main__":
    main()

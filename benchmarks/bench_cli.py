"""Command-line latency: every ``jaxmesh`` command on a small mesh, cold and warm, in one run.

    .venv/bin/python benchmarks/bench_cli.py [--mesh spot] [--keep F] [--repeat 3] [--commands info,hash]
                                             [--against DIR]

Each command runs as a user types it (a fresh process of the installed ``jaxmesh``
executable), first with an empty compilation cache (``JAXMESH_CACHE_DIR`` a new empty
folder: "cold"), then ``--repeat`` more times with the cache that run filled ("warm",
the median reported).  Two floors are measured the same way: a bare ``python -c pass``
and ``python -c "import jax"`` (every computing command imports JAX).  Inputs: the
shared mesh (``../shared/meshes/``, default spot, 2,930 vertices), a noisy copy of it and
its ``.jxm`` file, made once before the timings; ``--keep F`` first simplifies the mesh to
the fraction F of its faces (``jaxmesh.hashing.attacks.simplify``: ``--keep 0.615`` makes
spot a mesh of about 1,800 vertices).  ``--against DIR`` times another checkout of jaxmesh
(``DIR`` its root, e.g. a ``git worktree`` of an older commit) beside this one: every
command runs as ``python -m jaxmesh`` with ``PYTHONPATH`` set to each root in turn, the
two alternating run by run (the machine's drift falls on both), each with its own cache,
and the table gets both columns and their ratio.  The row *denoise (blind default) on another
size* denoises a second noisy mesh, the first simplified to 98% of its faces, starting from
the cache the blind default's own row filled ("empty cache" there means: no program of this
size yet): what a user denoising one scan after another meets.  Not part of the test suite:
numbers depend on the machine; compare the rows of one run.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SHARED = Path(__file__).resolve().parents[2] / "shared" / "meshes"
ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


#: the row of the blind default on a mesh of another size, its cache filled by the blind default's row
ANOTHER_SIZE = "denoise (blind default) on another size"
#: the fraction of the mesh's faces the other size keeps
OTHER_KEEP = 0.98


def commands(mesh: Path, tmp: Path) -> dict[str, list[str]]:
    """Each command's words (``jaxmesh`` left out); outputs go to ``tmp``, overwritten."""
    noisy, packed = tmp / "noisy.ply", tmp / "mesh.jxm"
    return {
        "--help": ["--help"],
        "info": ["info", str(mesh)],
        "convert": ["convert", str(mesh), str(tmp / "out.obj"), "--force"],
        "noise": ["noise", str(mesh), str(tmp / "out-noise.ply"), "--force"],
        "denoise (blind default)": ["denoise", str(noisy), str(tmp / "out-a.ply"), "--force"],
        ANOTHER_SIZE: ["denoise", str(tmp / "noisy-other.ply"), str(tmp / "out-a2.ply"), "--force"],
        "denoise --method taubin": ["denoise", str(noisy), str(tmp / "out-t.ply"), "--method", "taubin", "--force"],
        "denoise --method kernel": ["denoise", str(noisy), str(tmp / "out-k.ply"), "--method", "kernel", "--force"],
        "denoise --method learned": ["denoise", str(noisy), str(tmp / "out-l.ply"), "--method", "learned", "--force"],
        "hash": ["hash", str(mesh)],
        "compress": ["compress", str(mesh), str(tmp / "out.jxm"), "--force"],
        "decompress": ["decompress", str(packed), str(tmp / "out-d.ply"), "--force"],
        "view": ["view", str(mesh), "-o", str(tmp / "out.html"), "--force"],
        "stats": ["stats", str(mesh)],
    }


def seconds(argv: list[str], cache: Path, root: Path | None = None) -> float:
    """Wall seconds of ``argv`` with the compilation cache ``cache`` (and jaxmesh imported from
    ``root`` when given)."""
    env = {**os.environ, "JAXMESH_CACHE_DIR": str(cache), **({"PYTHONPATH": str(root)} if root else {})}
    start = time.perf_counter()
    # run from the scratch folder: `python -m` puts the working folder ahead of PYTHONPATH
    done = subprocess.run(argv, env=env, capture_output=True, text=True, cwd=cache.parent)
    took = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return took


def jaxmesh_module():
    import jaxmesh

    return jaxmesh


def simplified(mesh: Path, keep: float, out: Path) -> Path:
    """``mesh`` simplified to the fraction ``keep`` of its faces, written to ``out``."""
    from jaxmesh.hashing.attacks import simplify

    jm = jaxmesh_module()
    jm.save(simplify(jm.load(mesh), keep), out)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="spot", help="a mesh of ../shared/meshes (its name without .ply)")
    ap.add_argument("--repeat", type=int, default=3, help="warm runs per command (median)")
    ap.add_argument("--commands", default="", help="comma-separated subset of the rows (default: all)")
    ap.add_argument("--keep", type=float, default=1.0, help="simplify the mesh to this fraction of its faces first")
    ap.add_argument("--against", type=Path, default=None, metavar="DIR",
                    help="the root of another jaxmesh checkout, timed beside this one")
    args = ap.parse_args()
    if args.against is not None and not (args.against / "jaxmesh" / "__init__.py").is_file():
        raise SystemExit(f"{args.against}: not the root of a jaxmesh checkout (no jaxmesh/__init__.py)")
    mesh = SHARED / f"{args.mesh}.ply"
    if not mesh.is_file():
        raise SystemExit(f"{mesh}: not found (the shared meshes sit beside the repository)")
    jaxmesh = shutil.which("jaxmesh", path=str(BIN)) or "jaxmesh"
    python = sys.executable
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        setup = tmp / "setup-cache"
        if args.keep != 1.0:
            mesh = simplified(mesh, args.keep, tmp / f"{args.mesh}-{args.keep}.ply")
        vertices = jaxmesh_module().load(mesh).num_vertices
        seconds([jaxmesh, "noise", str(mesh), str(tmp / "noisy.ply"), "--sigma", "0.3"], setup)
        seconds([jaxmesh, "compress", str(mesh), str(tmp / "mesh.jxm")], setup)
        other = simplified(mesh, OTHER_KEEP, tmp / "other.ply")
        other_vertices = jaxmesh_module().load(other).num_vertices
        seconds([jaxmesh, "noise", str(other), str(tmp / "noisy-other.ply"), "--sigma", "0.3"], setup)
        runner = [jaxmesh] if args.against is None else [python, "-m", "jaxmesh"]
        table = {"python -c pass (floor)": [python, "-c", "pass"],
                 "python -c 'import jax' (floor)": [python, "-c", "import jax"],
                 **{f"jaxmesh {name}": [*runner, *words] for name, words in commands(mesh, tmp).items()}}
        wanted = {w.strip() for w in args.commands.split(",") if w.strip()}
        caches: dict[str, Path] = {}
        for name, argv in table.items():
            if wanted and name.removeprefix("jaxmesh ") not in wanted and "floor" not in name:
                continue
            caches[name] = tmp / f"cache-{len(rows)}"
            if name == f"jaxmesh {ANOTHER_SIZE}":
                _copy_caches(caches.get("jaxmesh denoise (blind default)"), caches[name])
            rows.append((name, *_timings(argv, caches[name], args.repeat,
                                         None if "floor" in name else args.against)))
            print(f"{name:32s} " + "   ".join(f"{t:6.2f} s" for t in rows[-1][1:]), file=sys.stderr)
    print(f"\n{args.mesh} ({vertices} vertices; another size: {other_vertices}): each command a fresh process; "
          f"warm = median of {args.repeat}\n")
    if args.against is None:
        print("| command | empty cache | warm cache |\n|---|---|---|")
        for name, cold, warm in rows:
            print(f"| `{name}` | {cold:.2f} s | {warm:.2f} s |")
        return
    print(f"| command | empty cache | warm cache | {args.against}: empty | {args.against}: warm | warm ratio |")
    print("|---|---|---|---|---|---|")
    for name, cold, warm, *other in rows:
        cells = ["", "", ""] if not other else [f"{other[0]:.2f} s", f"{other[1]:.2f} s", f"{warm / other[1]:.2f}"]
        print(f"| `{name}` | {cold:.2f} s | {warm:.2f} s | " + " | ".join(cells) + " |")


def _copy_caches(source: Path | None, target: Path) -> None:
    """Start ``target`` (and its ``-this``/``-other`` twins of ``--against``) from ``source``'s contents."""
    if source is None:
        raise SystemExit(f"the row '{ANOTHER_SIZE}' needs the row 'denoise (blind default)' before it")
    for suffix in ("", "-this", "-other"):
        if source.with_name(source.name + suffix).is_dir():
            shutil.copytree(source.with_name(source.name + suffix), target.with_name(target.name + suffix))


def _timings(argv: list[str], cache: Path, repeat: int, against: Path | None) -> tuple[float, ...]:
    """(cold, warm median) of ``argv`` from this checkout, and with ``against`` the same for that
    checkout, the two alternating run by run."""
    if against is None:
        return seconds(argv, cache), statistics.median(seconds(argv, cache) for _ in range(repeat))
    runs = {"this": (ROOT, []), "other": (against, [])}
    for _ in range(repeat + 1):
        for which, (root, times) in runs.items():
            times.append(seconds(argv, cache.with_name(f"{cache.name}-{which}"), root))
    return tuple(x for _, times in runs.values() for x in (times[0], statistics.median(times[1:])))


if __name__ == "__main__":
    main()

"""A dataset of distinct meshes through the dataset runner, a loop of single
jaxmesh calls, and a loop of Open3D's Laplacian filter, in one run.

    .venv/bin/python benchmarks/bench_dataset.py [--count 200] [--data DIR] [--batch-size N] [--ladder R]
                                                 [--method NAME] [--variants ...]

**The dataset** (made once, kept in --data): ``--count`` distinct meshes of
1k–60k vertices from the shared meshes (../shared/meshes), each a source
mesh decimated (fast-simplification, quadric) or Loop-subdivided then
decimated to a target vertex count drawn log-uniform in [1000, 60000], with
isotropic Gaussian noise of 0.2 mean edge lengths; binary PLY.

**The job**: 10 umbrella (Laplacian) steps, λ = 0.5 (``--method NAME``: that method at
its registry defaults, for the jaxmesh variants), on every mesh, read
from and written to disk:

* *runner*: :func:`jaxmesh.dataset.denoise_files` with its defaults (the umbrella
  flow is ``local``, so the meshes run packed into disjoint unions of up to 61,440
  vertices, one compile per union shape; read-ahead and write-behind threads);
* *runner-padded*: the same with ``pack=False``: size buckets of padded batches,
  one compile per bucket shape (the runner's path for methods that are not local);
* *loop*: for each file ``load`` → :func:`~jaxmesh.denoise.denoise_in_unit_frame`
  (``umbrella_flow``) → ``save``: one compile per distinct mesh size;
* *runner-previous*: the runner with its former defaults (batches
  of 16, ladder 2^¼);
* *runner-xla-defaults*: the runner with XLA's own CPU compiler settings (the
  other jaxmesh variants run as the ``jaxmesh`` command does, with
  :func:`jaxmesh.compiler.prefer_fast_cpu_compiles`);
* *open3d*: ``read_triangle_mesh`` → ``filter_smooth_laplacian(10, 0.5)`` →
  ``write_triangle_mesh``.

Each runs in a fresh subprocess (its peak RSS is its own), after ``os.sync()``
(so the previous variant's writes are not flushed during this one), ``--repeat``
times interleaved (the loop once); compile counts and times come from JAX's
compile events.  Prints every run, the medians and their ratios (Open3D's time
alone varied from 8.5 to 18.4 s between runs on this machine).
Not part of the test suite: compare ratios, not seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("bunny", "igea", "armadillo", "fertility", "human", "maxplanck", "camelhead", "shark", "fandisk", "cow")
ITERATIONS, LAM = 10, 0.5


def make_dataset(folder: Path, count: int) -> list[Path]:
    import fast_simplification
    import jax
    import trimesh

    jax.config.update("jax_enable_x64", True)
    import jaxmesh

    sys.path.insert(0, str(ROOT / "experiments"))
    from shared_meshes import load as load_shared

    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    targets = np.exp(rng.uniform(np.log(1000), np.log(60000), count)).astype(int)
    paths = []
    for i, target in enumerate(targets):
        path = folder / f"mesh{i:04d}.ply"
        paths.append(path)
        if path.exists():
            continue
        src = load_shared(SOURCES[i % len(SOURCES)])
        v, f = np.asarray(src.vertices, np.float64), np.asarray(src.faces)
        while len(v) < 1.2 * target:
            t = trimesh.Trimesh(v, f, process=False).subdivide_loop()
            v, f = np.asarray(t.vertices), np.asarray(t.faces)
        v, f = fast_simplification.simplify(np.array(v, np.float64, order="C"), np.array(f, np.int32, order="C"),
                                            1.0 - target / len(v))
        t = trimesh.Trimesh(v, f, process=True)          # merge, drop degenerate faces and unused vertices
        t.update_faces(t.nondegenerate_faces())
        t.remove_unreferenced_vertices()
        mesh = jaxmesh.Mesh.from_arrays(np.asarray(t.vertices, np.float64), np.asarray(t.faces))
        jaxmesh.save(jaxmesh.add_noise(mesh, 0.2, i), str(path), overwrite=True)
    return paths


def _compile_listener(box: dict):
    import jax

    def on_event(event, duration, **kwargs):
        if event == "/jax/core/compile/backend_compile_duration":
            box["count"] += 1
            box["seconds"] += duration

    jax.monitoring.register_event_duration_secs_listener(on_event)


def _job(method: str) -> dict:
    """The method's parameters in the job: the umbrella flow's 10 steps of λ = 0.5, else the registry's defaults."""
    return {"iterations": ITERATIONS, "lam": LAM} if method == "umbrella_flow" else {}


def run_variant(name: str, data: Path, out: Path, batch_size: int, ladder: float,
                method: str = "umbrella_flow") -> dict:
    files = sorted(data.glob("*.ply"))
    out.mkdir(parents=True, exist_ok=True)
    comp = {"count": 0, "seconds": 0.0}
    start = time.perf_counter()
    extra = {}
    if name == "open3d":
        import open3d as o3d

        for p in files:
            m = o3d.io.read_triangle_mesh(str(p))
            m = m.filter_smooth_laplacian(number_of_iterations=ITERATIONS, lambda_filter=LAM)
            o3d.io.write_triangle_mesh(str(out / p.name), m)
    else:
        from jaxmesh.compiler import prefer_fast_cpu_compiles

        extra["xla_flag"] = False if name.endswith("-xla-defaults") else prefer_fast_cpu_compiles()
        import jax

        jax.config.update("jax_enable_x64", True)
        _compile_listener(comp)
        import jaxmesh
        from jaxmesh.dataset import denoise_files
        from jaxmesh.denoise import denoise_in_unit_frame

        start = time.perf_counter()
        if name.startswith("runner"):
            if name == "runner-previous":      # the former defaults: batches of 16, ladder 2^¼
                batch_size, ladder = 16, 2 ** 0.25
            pack = False if name in ("runner-padded", "runner-previous") else None
            s = denoise_files([str(data)], out, method, _job(method),
                              batch_size=batch_size, ladder=ladder, overwrite=True, pack=pack)
            extra |= {"batch_size": batch_size or "default", "ladder": round(ladder, 4),
                      "padding_waste": round(s.waste, 3), "failed": s.failed, "batch_shapes": s.compiles}
        else:
            for p in files:
                m = denoise_in_unit_frame(jaxmesh.load(str(p)), method, **_job(method))
                jaxmesh.save(m, str(out / p.name), overwrite=True)
    seconds = time.perf_counter() - start
    return {"variant": name, "meshes": len(files), "seconds": round(seconds, 2),
            "meshes_per_second": round(len(files) / seconds, 2), "compiles": comp["count"],
            "compile_seconds": round(comp["seconds"], 2),
            "peak_rss_mb": peak_rss_mb(), **extra}


def peak_rss_mb() -> int:
    """VmHWM of this process (reset by exec, unlike getrusage's ru_maxrss, which keeps the parent's peak)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return round(int(line.split()[1]) / 1024)
    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--count", type=int, default=200)
    ap.add_argument("--data", type=Path, default=Path(tempfile.gettempdir()) / "jaxmesh-bench-dataset")
    ap.add_argument("--batch-size", type=int, default=None, help="meshes per call (default: the runner's own)")
    ap.add_argument("--ladder", type=float, default=2 ** 0.5, help="ratio between padded sizes (the runner's default)")
    ap.add_argument("--variants", nargs="*",
                    default=["runner", "runner-padded", "runner-previous", "runner-xla-defaults", "loop", "open3d"])
    ap.add_argument("--repeat", type=int, default=3, help="runs of each fast variant, interleaved (medians)")
    ap.add_argument("--method", default="umbrella_flow",
                    help="the runner's and the loop's method (default umbrella_flow, 10 steps of λ = 0.5, which "
                         "Open3D's filter matches; any other runs at the registry's defaults)")
    ap.add_argument("--variant", help=argparse.SUPPRESS)
    args = ap.parse_args()
    data = args.data / f"in{args.count}"
    if args.variant:
        print(json.dumps(run_variant(args.variant, data, args.data / f"out-{args.variant}", args.batch_size,
                                     args.ladder, args.method)))
        return
    t = time.perf_counter()
    paths = make_dataset(data, args.count)
    sizes = []
    for p in paths:   # vertex counts from the PLY headers
        with open(p, "rb") as fh:
            head = fh.read(400).decode("latin-1")
        sizes.append(int(head.split("element vertex ")[1].split()[0]))
    print(f"dataset: {len(paths)} meshes, {min(sizes)}–{max(sizes)} vertices (median {int(np.median(sizes))}), "
          f"{len(set(sizes))} distinct sizes; made/checked in {time.perf_counter() - t:.0f} s", flush=True)
    rows: dict[str, list[dict]] = {}
    for rep in range(args.repeat):      # interleaved repeats; the slow loop runs once
        for name in args.variants:
            if rep and name == "loop":
                continue
            os.sync()                   # the previous variant's 200 written files do not land in this one
            cmd = [sys.executable, __file__, "--variant", name, "--method", args.method, "--count", str(args.count),
                   "--data", str(args.data), "--ladder", str(args.ladder)]
            cmd += [] if args.batch_size is None else ["--batch-size", str(args.batch_size)]
            res = subprocess.run(cmd, capture_output=True, text=True)
            if res.returncode:
                print(f"{name}: failed\n{res.stderr[-2000:]}")
                continue
            rows.setdefault(name, []).append(json.loads(res.stdout.strip().splitlines()[-1]))
            print(json.dumps(rows[name][-1]), flush=True)
    median = {name: float(np.median([r["meshes_per_second"] for r in runs])) for name, runs in rows.items()}
    for name, runs in rows.items():
        rates = sorted(r["meshes_per_second"] for r in runs)
        print(f"{name}: median {median[name]:.2f} meshes/s over {len(runs)} run(s) (range {rates[0]}–{rates[-1]})")
    if "runner" in median:
        for peer in ("runner-padded", "runner-previous", "runner-xla-defaults", "loop", "open3d"):
            if peer in median:
                print(f"runner / {peer}: {median['runner'] / median[peer]:.2f}x meshes per second (medians)")

if __name__ == "__main__":
    main()

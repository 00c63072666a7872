"""``jaxmesh._private.dot`` (a 3-component dot product written out) against
``jnp.sum(a * b, axis=-1)``, on the two patterns that use it: the edge tilts of
the blind chooser's estimate (a gathered (D, F, 3, 3) array against broadcast
face normals) and the vertex update's projection ((F, 3, 3) against (F, 1, 3)).

    .venv/bin/python benchmarks/bench_dot.py [--mesh bunny]

Steady-state milliseconds per jitted call, float32 and float64, under the
``jaxmesh`` command's XLA flag (:mod:`jaxmesh.compiler`).  Compare ratios.
"""

from __future__ import annotations

import argparse
import time

from jaxmesh.compiler import prefer_fast_cpu_compiles

prefer_fast_cpu_compiles()

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402

import jaxmesh  # noqa: E402
from jaxmesh._private import dot  # noqa: E402
from jaxmesh.geometry import face_normals  # noqa: E402


def ms(f, *args, repeat: int = 30) -> float:
    jax.block_until_ready(f(*args))
    t = time.perf_counter()
    for _ in range(repeat):
        jax.block_until_ready(f(*args))
    return (time.perf_counter() - t) / repeat * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default="bunny", choices=("bunny", "spot"))
    args = ap.parse_args()
    print("| pattern | dtype | jnp.sum(a * b, -1) ms | dot ms | ratio |")
    print("|---|---|---|---|---|")
    for dtype in ("float32", "float64"):
        mesh = jaxmesh.data.load_sample(args.mesh, dtype=dtype)
        faces, nu = mesh.faces, face_normals(mesh)
        u = jax.random.normal(jax.random.PRNGKey(0), (2,) + mesh.vertices.shape, mesh.dtype)
        cases = {
            "edge tilt: u[faces] · ν_f": (lambda f: jax.jit(lambda u: f(u[..., faces, :], nu[None, :, None, :])), u),
            "vertex update: offset · n_f": (lambda f: jax.jit(
                lambda x: f(x[faces] - jnp.mean(x[faces], axis=-2)[:, None, :], nu[:, None, :])), mesh.vertices),
        }
        for name, (build, arg) in cases.items():
            plain = ms(build(lambda a, b: jnp.sum(a * b, axis=-1)), arg)
            written = ms(build(dot), arg)
            print(f"| {name} | {dtype} | {plain:.3f} | {written:.3f} | {plain / written:.2f} |")


if __name__ == "__main__":
    main()

"""Shared fixtures and helpers: small hand-checkable meshes, the shared real meshes
(skipped when ../shared/meshes is absent), plain-loop references used by several
files, the CLI tests' inputs (tests/cli), x64, strict dtype promotion, and rank
promotion that raises."""

from __future__ import annotations

import inspect
import json
import os
import re
import shutil
import tempfile
from pathlib import Path

# The default run is mostly XLA compiles of small programs that then run once (in
# tests/test_tune.py and tests/test_denoise_methods.py, 84 of 130 s were XLA compiles).
# With XLA's backend optimisation off they compile about a quarter faster, and with the
# older elemental fusion emitters instead of the MLIR ones about half as long again (the
# tuner's program on spot: 1.35 s -> 0.67 s, the same loss to the last digit); the
# results agree within every test's tolerance.  JAXMESH_TEST_XLA_OPTIMIZE=1 keeps XLA's
# defaults, the code users run: .ci/run's slow pass sets it.  Set before JAX starts its
# backend, and inherited by the subprocesses the tests start.
if os.environ.get("JAXMESH_TEST_XLA_OPTIMIZE") != "1":
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " --xla_backend_optimization_level=0"
                               " --xla_llvm_disable_expensive_passes=true"
                               " --xla_cpu_use_fusion_emitters=false").strip()

os.environ["JAX_NUMPY_RANK_PROMOTION"] = "raise"
# The CLI's persistent compilation cache stays off in the tests (in-process CLI calls would
# turn it on for the whole worker and write under the user's home); tests/test_compiler.py
# checks it in subprocesses with a folder of their own.
os.environ["JAXMESH_CACHE_DIR"] = "off"
# One BLAS / OpenMP thread per process: pytest-xdist runs one worker per core, and the
# host solvers (CHOLMOD through cholespy, LAPACK) otherwise start a thread per core in
# every worker, whose spinning threads slow the other worker down (a CLI test went from
# 1.3 s alone to 15 s in the full run).  Set when the controller loads this file, before
# the workers start, so they inherit it before they load numpy.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import jax  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
import trimesh  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
# Rank promotion raises, as in equinox's and optimistix's suites: the library writes
# every broadcast between ranks explicitly (``_private.lift``).  The environment
# variable carries the setting into the CLI subprocesses the tests start.
jax.config.update("jax_numpy_rank_promotion", "raise")
# One persistent compilation cache for the run, shared by the xdist workers: a program one
# worker compiled, the other loads, and a module whose programs were released
# (_release_compiled_programs) loads them back (the default run on 2 cores: 5 min 30 s
# without it, 4 min 55 s to 5 min 15 s with it).  The controller makes the folder before the workers
# start (they inherit the variable) and removes it at the end.  A size limit turns on
# JAX's file lock, so a worker never reads an entry the other is still writing.
if "JAXMESH_TEST_XLA_CACHE" not in os.environ:
    os.environ["JAXMESH_TEST_XLA_CACHE"] = _OWN_XLA_CACHE = tempfile.mkdtemp(prefix="jaxmesh-test-xla-")
else:
    _OWN_XLA_CACHE = None
jax.config.update("jax_compilation_cache_dir", os.environ["JAXMESH_TEST_XLA_CACHE"])
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.05)
jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
jax.config.update("jax_compilation_cache_max_size", 2**32)


def pytest_unconfigure(config):
    if _OWN_XLA_CACHE is not None:
        shutil.rmtree(_OWN_XLA_CACHE, ignore_errors=True)

import jaxmesh  # noqa: E402
from jaxmesh.compiler import release_compiled_programs  # noqa: E402

SHARED_MESHES = Path(
    os.environ.get("JAXMESH_SHARED_MESHES", Path(__file__).resolve().parents[1].parent / "shared" / "meshes")
)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """Drop JAX's compiled programs after a test module once the process holds many
    memory mappings.  Every XLA executable holds some; a whole-suite process that
    keeps them all passes the kernel's vm.max_map_count (65,530) and XLA crashes
    (SIGSEGV) in its next compile.  Below the limit the caches are kept, so modules
    share compiled programs (:func:`jaxmesh.compiler.release_compiled_programs`)."""
    yield
    release_compiled_programs()


# The suite runs with jaxtyping + beartype checking jaxmesh's annotations (pyproject's
# --jaxtyping-packages); a run without them (-p no:jaxtyping) checks only the library's
# own validation.
# (a function that no other decorator wraps: the formula functions' one_program keeps __wrapped__)
TYPECHECKED = hasattr(jaxmesh.operators.degree, "__wrapped__")


def assert_refused(fn, *args, param: str, message: str, error=ValueError, **kwargs):
    """``fn(*args, **kwargs)`` passes ``param`` a value its annotation excludes (a
    string outside a ``Literal[...]``, an object of the wrong type): when the
    annotations are checked, the checker's TypeError names ``param``; and the
    library's own validation (the unwrapped function, what users run) raises
    ``error`` matching ``message``."""
    if TYPECHECKED:
        with pytest.raises(TypeError, match=f"parameter '{param}'"):
            fn(*args, **kwargs)
    with pytest.raises(error, match=message):
        inspect.unwrap(fn)(*args, **kwargs)


def shared_mesh_path(name: str) -> Path:
    """Path of a mesh in ../shared/meshes, or skip the test with the reason."""
    p = SHARED_MESHES / name
    if not p.is_file():
        pytest.skip(f"shared mesh {name} not found under {SHARED_MESHES} "
                    "(set JAXMESH_SHARED_MESHES or check out ../shared beside the repo)")
    return p


def tetrahedron_arrays():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])  # outward
    return v, f


def octahedron_arrays():
    v = np.array([[1.0, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
    f = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4],
                  [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    return v, f


def _split_quads(nx: int, ny: int, idx) -> np.ndarray:
    """Two triangles (a, b, c), (a, c, d) per quad (i, j) of an nx × ny grid whose
    corner (i, j) is vertex ``idx(i, j)``."""
    f = []
    for i in range(nx):
        for j in range(ny):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            f += [[a, b, c], [a, c, d]]
    return np.array(f)


def grid_arrays(nx: int = 4, ny: int = 3, jitter: float = 0.0, seed: int = 0):
    """Open (nx+1) x (ny+1) grid in the z = 0 plane, two triangles per cell."""
    xs, ys = np.meshgrid(np.arange(nx + 1, dtype=float), np.arange(ny + 1, dtype=float), indexing="ij")
    v = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    if jitter:
        rng = np.random.default_rng(seed)
        v = v + jitter * rng.standard_normal(v.shape)
    return v, _split_quads(nx, ny, lambda i, j: i * (ny + 1) + j)


@pytest.fixture
def tetra():
    return jaxmesh.Mesh.from_arrays(*tetrahedron_arrays())


@pytest.fixture
def octa():
    return jaxmesh.Mesh.from_arrays(*octahedron_arrays())


@pytest.fixture
def triangle():
    return jaxmesh.Mesh.from_arrays(np.array([[0.0, 0, 0], [3, 0, 0], [0, 4, 0]]), np.array([[0, 1, 2]]))


@pytest.fixture
def grid():
    return jaxmesh.Mesh.from_arrays(*grid_arrays())


@pytest.fixture
def bumpy_grid():
    v, f = grid_arrays(5, 4, jitter=0.15, seed=1)
    return jaxmesh.Mesh.from_arrays(v, f)


@pytest.fixture(scope="session")
def spot():
    return jaxmesh.data.load_sample("spot", dtype=np.float64)


def torus_arrays(n: int = 8, m: int = 6, big: float = 2.0, small: float = 0.7):
    """A genus-1 torus, n x m quads split in two."""
    u, w = np.meshgrid(np.arange(n) * 2 * np.pi / n, np.arange(m) * 2 * np.pi / m, indexing="ij")
    v = np.stack([(big + small * np.cos(w)) * np.cos(u), (big + small * np.cos(w)) * np.sin(u),
                  small * np.sin(w)], -1).reshape(-1, 3)
    return v, _split_quads(n, m, lambda i, j: (i % n) * m + (j % m))


def loop_cotangent_matrix(v, f):
    """Plain-loop assembly of W_ij = cot α_ij + cot β_ij (independent reference)."""
    m = len(v)
    w = np.zeros((m, m))
    for tri in f:
        for k in range(3):
            i, j, o = tri[(k + 1) % 3], tri[(k + 2) % 3], tri[k]
            a, b = v[i] - v[o], v[j] - v[o]
            cot = np.dot(a, b) / np.linalg.norm(np.cross(a, b))
            w[i, j] += cot
            w[j, i] += cot
    return w


def write_dataset(folder, count=7):
    """``count`` small noisy meshes of three sizes (spheres and subdivided boxes, some
    with a boundary and isolated vertices) as PLY files in a new ``folder``."""
    folder.mkdir()
    rng = np.random.default_rng(1)
    paths = []
    for i in range(count):
        base = trimesh.creation.icosphere(subdivisions=1 + i % 3) if i % 2 else trimesh.creation.box().subdivide()
        v = base.vertices * (1 + i) + 0.02 * (1 + i) * rng.standard_normal(base.vertices.shape)
        faces = base.faces[: len(base.faces) - (i % 3)]          # some with a boundary (and isolated vertices)
        path = folder / f"m{i}.ply"
        jaxmesh.save(jaxmesh.Mesh.from_arrays(v, faces), str(path))
        paths.append(path)
    return paths


def write_pairs(tmp_path, count):
    """``count`` clean meshes in clean/ and their noisy copies (σ = 0.3 ℓ̄) under the
    same names in in/."""
    (tmp_path / "clean").mkdir()
    (tmp_path / "in").mkdir()
    names = []
    for i in range(count):
        s = trimesh.creation.icosphere(subdivisions=1)
        clean = jaxmesh.Mesh.from_arrays(s.vertices * (1 + i), s.faces)
        jaxmesh.save(clean, str(tmp_path / "clean" / f"p{i}.ply"))
        jaxmesh.save(jaxmesh.add_noise(clean, 0.3, i), str(tmp_path / "in" / f"p{i}.ply"))
        names.append(f"p{i}.ply")
    return names


def viewer_config(page: str) -> dict:
    """The JSON data a `jaxmesh view` page embeds."""
    m = re.search(r'<script type="application/json" id="data">(.*?)</script>', page, re.S)
    return json.loads(m.group(1).replace("<\\/", "</"))


@pytest.fixture(scope="session")
def small_pair(tmp_path_factory):
    """A noisy icosphere (642 vertices, σ = 0.3 ℓ̄) with one isolated vertex far away
    (so the boxes of all and of used vertices differ), and its clean original, as
    files.  The commands' logic does not need the 2.9k-vertex sample; the tests that
    tune share one compiled tuner through these shapes."""
    d = tmp_path_factory.mktemp("small")
    s = trimesh.creation.icosphere(3)
    clean = jaxmesh.Mesh.from_arrays(np.vstack([s.vertices, [[5.0, 5.0, 5.0]]]), s.faces, warn=False)
    noisy = jaxmesh.add_noise(clean, 0.3, 7)
    noisy = noisy.with_vertices(noisy.vertices.at[-1].set(clean.vertices[-1]))
    paths = str(d / "noisy.ply"), str(d / "clean.ply")
    jaxmesh.save(noisy, paths[0])
    jaxmesh.save(clean, paths[1])
    return paths

"""Every registered denoiser: jit vs eager, batch vs loop, invariances, finite
differences, degenerate input, and the registry's argument checking."""

import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import trimesh
from jax.test_util import check_grads

import jaxmesh
from jaxmesh.denoise import METHODS, denoise, diverged
from jaxmesh.metrics import visual_error

NAMES = sorted(METHODS)
SCALE_FREE = [n for n in NAMES if n != "kernel"]  # λ of the kernel flow is a squared length
# L0 solves to a relative residual of 1e-4 with CG: a batch runs until every element
# has converged, so the elements agree with single runs to that accuracy, not to rounding
SOLVER_ATOL = {"l0": 1e-6}
HEAVY_ON_SPOT = ("l0",)   # 40 CG solves on the 2.9k-vertex spot: -m slow
# central-difference steps where the default (1e-4) leaves a truncation error above the
# tolerance: bilateral normal filtering's narrow range kernel is strongly curved
# (error 9.2e-5 relative at 1e-4, 9.2e-7 at 1e-5, 9e-9 at 1e-6: O(eps²), the gradient is exact)
FD_EPS = {"bilateral_normal": 1e-6}


@pytest.fixture(scope="module")
def noisy_spot():
    clean = jaxmesh.normalize(jaxmesh.data.load_sample("spot", dtype=np.float64))
    return clean, jaxmesh.add_noise(clean, 0.3, jax.random.PRNGKey(0))


@pytest.fixture(scope="module")
def small_sphere():
    s = trimesh.creation.icosphere(1)
    rng = np.random.default_rng(3)
    return jaxmesh.Mesh.from_arrays(s.vertices + 0.03 * rng.standard_normal(s.vertices.shape), s.faces)


def _spot_cases(names=None):
    return [pytest.param(n, marks=[pytest.mark.slow] if n in HEAVY_ON_SPOT else []) for n in (names or NAMES)]


@pytest.mark.parametrize("name", _spot_cases())
def test_denoises_spot(noisy_spot, name):
    clean, noisy = noisy_spot
    out = METHODS[name](noisy)
    assert np.all(np.isfinite(np.asarray(out.vertices)))
    assert float(visual_error(clean, out)) < 0.8 * float(visual_error(clean, noisy))


@pytest.mark.parametrize("name", NAMES)
def test_jit_equals_eager_and_batch_equals_loop(small_sphere, name):
    method = METHODS[name]
    eager = method(small_sphere).vertices
    # the normal-filtering methods need their face graph from the host when traced
    aux = method.prepare(small_sphere)
    jitted = eqx.filter_jit(lambda m, aux: method(m, **aux))(small_sphere, aux).vertices
    np.testing.assert_allclose(jitted, eager, rtol=1e-9, atol=1e-11)
    keys = jax.random.split(jax.random.PRNGKey(1), 3)
    copies = jnp.stack([jaxmesh.add_noise(small_sphere, 0.1, k).vertices for k in keys])
    batched = method(small_sphere.with_vertices(copies)).vertices
    for b in range(3):
        single = method(small_sphere.with_vertices(copies[b])).vertices
        np.testing.assert_allclose(batched[b], single, rtol=1e-8, atol=SOLVER_ATOL.get(name, 1e-10))


def assert_same_up_to_median_ties(name, b, a):
    """The angle median is a discrete choice: rounding can flip a near tie, which
    moves a few vertices by a fraction of an edge.  Everything else must agree."""
    if name != "normal_median":
        np.testing.assert_allclose(b, a, atol=max(1e-9, SOLVER_ATOL.get(name, 0)))
        return
    err = np.linalg.norm(np.asarray(b - a), axis=1)
    assert np.median(err) < 1e-9 and err.max() < 0.02


@pytest.mark.parametrize("name", _spot_cases())
def test_translation_invariance(noisy_spot, name):
    _, noisy = noisy_spot
    shift = jnp.array([0.5, -0.3, 0.2])
    a = METHODS[name](noisy).vertices
    b = METHODS[name](noisy.with_vertices(noisy.vertices + shift)).vertices - shift
    assert_same_up_to_median_ties(name, b, a)


@pytest.mark.parametrize("name", _spot_cases(SCALE_FREE))
def test_scale_invariance(noisy_spot, name):
    _, noisy = noisy_spot
    a = METHODS[name](noisy).vertices
    b = METHODS[name](noisy.with_vertices(1000.0 * noisy.vertices)).vertices / 1000.0
    assert_same_up_to_median_ties(name, b, a)


def _slow_if(heavy, name, *rest):
    """Cases over ~25 s (FEM / CG inside, slow to compile) run with -m slow; every method
    keeps a finite-difference check in the default run (positions, below)."""
    return pytest.param(name, *rest, marks=[pytest.mark.slow] if name in heavy else [])


def _continuous_cases():
    return [_slow_if(("geometric",), n, p) for n in NAMES for p in METHODS[n].continuous]


@pytest.mark.parametrize("name,param", _continuous_cases())
def test_gradient_in_each_continuous_parameter(small_sphere, name, param):
    method = METHODS[name]
    w = jax.random.normal(jax.random.PRNGKey(2), small_sphere.vertices.shape)
    base = method.defaults()[param]

    def loss(p):  # one iteration: the loop body is what is differentiated
        return jnp.sum(w * method(small_sphere, iterations=1, **{param: p}).vertices)

    check_grads(loss, (jnp.asarray(float(base)),), order=1, modes=("fwd", "rev"), atol=1e-5, rtol=1e-4)


# guided filtering chooses patches by an argmin: on the jittered sphere near ties flip under
# finite-difference steps; its position gradient is checked on a box, where the choice is
# stable (test_feature_denoise.py)
@pytest.mark.parametrize("name", [n for n in NAMES if n != "guided_normal"])
def test_gradient_in_the_positions(small_sphere, name):
    method = METHODS[name]
    w = jax.random.normal(jax.random.PRNGKey(4), small_sphere.vertices.shape)

    def loss(x):
        return jnp.sum(w * method(small_sphere.with_vertices(x), iterations=1).vertices)

    check_grads(loss, (small_sphere.vertices,), order=1, modes=("rev",), atol=1e-5, rtol=1e-4,
                eps=FD_EPS.get(name))


@pytest.mark.parametrize("name", [_slow_if(("geometric", "cotangent_implicit"), n) for n in
                                  ["kernel", "taubin", "cotangent_implicit", "bilateral", "geometric"]])
def test_float32_gradients_are_finite_and_close_to_float64(small_sphere, name):
    method = METHODS[name]
    param = method.continuous[0]
    base = float(method.defaults()[param])
    w = jax.random.normal(jax.random.PRNGKey(5), small_sphere.vertices.shape)

    def grad(dtype):
        m = small_sphere.astype(dtype)
        f = lambda p: jnp.sum(w.astype(dtype) * method(m, **{param: p}).vertices)  # noqa: E731
        return jax.grad(f)(jnp.asarray(base, dtype))

    g32, g64 = grad(jnp.float32), grad(jnp.float64)
    assert g32.dtype == jnp.float32 and np.isfinite(float(g32))
    np.testing.assert_allclose(float(g32), float(g64), rtol=2e-2, atol=1e-4)


def degenerate_meshes():
    """A zero-length edge (vertex 5 coincides with vertex 0), an isolated vertex
    (6), a degree-2 vertex on a boundary fin (4) and a zero-area face (1, 7, 8
    collinear)."""
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [0, 0, 0],
                  [5, 5, 5], [2, 0, 0], [1.5, 0, 0]])
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [1, 4, 2], [3, 5, 0], [1, 7, 8]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", jaxmesh.MeshWarning)
        return jaxmesh.Mesh.from_arrays(v, f)


@pytest.mark.parametrize("name", NAMES)
def test_degenerate_input_gives_finite_output(name):
    mesh = degenerate_meshes()
    out = METHODS[name](mesh).vertices
    assert np.all(np.isfinite(np.asarray(out)))
    np.testing.assert_array_equal(out[6], mesh.vertices[6])   # isolated vertex stays put
    grads = jax.grad(lambda x: jnp.sum(METHODS[name](mesh.with_vertices(x)).vertices ** 2))(mesh.vertices)
    assert np.all(np.isfinite(np.asarray(grads)))


@pytest.mark.parametrize("lam", [1e-12, 1e-6, 1e-3, 1e-1, 1.0, 1e6])
def test_safeguarded_kernel_flow_never_diverges(noisy_spot, lam):
    _, noisy = noisy_spot
    out = denoise(noisy, "kernel", lam=lam, iterations=5)
    assert np.all(np.isfinite(np.asarray(out.vertices)))
    assert not bool(diverged(noisy, out))


def test_unguarded_kernel_flow_divergence_is_detected(noisy_spot):
    _, noisy = noisy_spot
    out = denoise(noisy, "kernel", lam=1e-3, iterations=5, safeguard=False)
    assert bool(diverged(noisy, out))
    assert not bool(diverged(noisy, denoise(noisy, "kernel", lam=1e-3, iterations=5)))


def test_registry_rejects_bad_arguments(tetra):
    with pytest.raises(ValueError, match="unknown method 'nope'"):
        denoise(tetra, "nope")
    with pytest.raises(ValueError, match=r"has no parameter\(s\) \['sigma'\]"):
        denoise(tetra, "kernel", sigma=1.0)
    with pytest.raises(ValueError, match="variant must be one of"):
        denoise(tetra, "kernel", variant="fast")
    with pytest.raises(ValueError, match="iterations must be a non-negative int"):
        denoise(tetra, "taubin", iterations=2.5)
    for name, method in METHODS.items():
        assert method.summary and method.reference
        for p in method.continuous:
            lo, hi = method.params[p].bounds
            assert lo < method.params[p].default < hi, (name, p)

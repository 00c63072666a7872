"""Every registered denoiser: jit vs eager, batch vs loop, invariances, finite
differences, degenerate input, and the registry's argument checking."""

import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import assert_refused
import trimesh
from jax.test_util import check_grads

import jaxmesh
from jaxmesh.denoise import METHODS, denoise, diverged
from jaxmesh.metrics import visual_error

NAMES = sorted(METHODS)
SCALE_FREE = [n for n in NAMES if n != "kernel"]  # λ of the kernel flow is a squared length
# methods whose results agree with a reference to a solver's tolerance, not to rounding (none:
# L0's default p-step is a direct solve)
SOLVER_ATOL: dict[str, float] = {}
HEAVY_ON_SPOT = ("l0",)   # 40 factorizations on the 2.9k-vertex spot (4.5 s): -m slow
# the learned stack's jit/vmap and finite-difference checks run by default in tests/test_learn.py
# (on small random models); here, on the shipped model, they run with -m slow
LEARN_COVERED = [pytest.param(n, marks=pytest.mark.slow) if n == "learned" else n for n in NAMES]
# jit/batch: these and the methods slowest to compile (2-5 s each) run with -m slow; each of
# those keeps its gradient, degenerate-input and invariance checks in the default run
JIT_CASES = [pytest.param(n, marks=pytest.mark.slow) if n in ("learned", "l0", "impulse_repair", "bilateral",
                                                              "geometric") else n for n in NAMES]
# central-difference steps where the default (1e-4) leaves a truncation error above the
# tolerance: bilateral normal filtering's narrow range kernel is strongly curved
# (error 9.2e-5 relative at 1e-4, 9.2e-7 at 1e-5, 9e-9 at 1e-6: O(eps²), the gradient is exact)
#: the learned stack's guided patch choice is piecewise constant: with the shipped model's
#: weights a step of 1e-6 on the jittered sphere already flips a patch (1e-7 agrees to 1e-8)
FD_EPS = {"bilateral_normal": 1e-6, "learned": 1e-7}


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


def compiled(method, mesh, max_traces=None, **static):
    """``x (*b, V, 3), **params -> method(mesh with x, **static)`` under one ``jit``, the
    host-built inputs (face graph) passed in: one compile serves every call of the same
    shapes.  ``static``: the integer and choice parameters (iterations, ...).
    ``max_traces``: fail (``eqx.debug.assert_max_traces``) if the flow is traced more
    often, i.e. if calls of the same shapes do not share the compiled program."""
    aux = method.prepare(mesh)

    def run(x, **p):
        return method(mesh.with_vertices(x), **aux, **static, **p).vertices

    return jax.jit(run if max_traces is None else eqx.debug.assert_max_traces(run, max_traces=max_traces))


@pytest.mark.parametrize("name", _spot_cases())
def test_denoises_spot_and_is_translation_and_scale_invariant(noisy_spot, name):
    """One compiled flow per method: it reduces the error on spot, and shifting (and,
    but for the kernel flow's λ, a squared length, scaling) the input shifts (scales)
    the output."""
    clean, noisy = noisy_spot
    f = compiled(METHODS[name], noisy, max_traces=1)    # shifted and scaled inputs reuse the program
    a = f(noisy.vertices)
    assert np.all(np.isfinite(np.asarray(a)))
    assert float(visual_error(clean, a)) < 0.8 * float(visual_error(clean, noisy))
    shift = jnp.array([0.5, -0.3, 0.2])
    assert_same_up_to_median_ties(name, f(noisy.vertices + shift[None]) - shift[None], a)
    if name in SCALE_FREE:
        assert_same_up_to_median_ties(name, f(1000.0 * noisy.vertices) / 1000.0, a)


@pytest.mark.parametrize("name", JIT_CASES)
def test_jit_equals_eager_and_batch_equals_loop(small_sphere, name):
    method = METHODS[name]
    with jax.disable_jit():     # an eager call runs one kept program (denoise._compiled): this is op by op
        eager = method(small_sphere).vertices
    f = compiled(method, small_sphere)
    atol = SOLVER_ATOL.get(name, 1e-11)     # an iterative solve op by op rounds differently: its tolerance
    np.testing.assert_allclose(method(small_sphere).vertices, eager, rtol=1e-9, atol=atol)
    np.testing.assert_allclose(f(small_sphere.vertices), eager, rtol=1e-9, atol=atol)
    keys = jax.random.split(jax.random.PRNGKey(1), 3)
    copies = jnp.stack([jaxmesh.add_noise(small_sphere, 0.1, k).vertices for k in keys])
    batched = f(copies)
    for b in range(3):
        np.testing.assert_allclose(batched[b], f(copies[b]), rtol=1e-8, atol=SOLVER_ATOL.get(name, 1e-10))


def assert_same_up_to_median_ties(name, b, a):
    """The angle median is a discrete choice: rounding can flip a near tie, which
    moves a few vertices by a fraction of an edge.  Everything else must agree."""
    if name != "normal_median":
        np.testing.assert_allclose(b, a, atol=max(1e-9, SOLVER_ATOL.get(name, 0)))
        return
    err = np.linalg.norm(np.asarray(b - a), axis=1)
    assert np.median(err) < 1e-9 and err.max() < 0.02


def _slow_if(heavy, name, *rest):
    """Cases over ~10 s (FEM / CG inside, slow to compile) run with -m slow; every method
    keeps a finite-difference check in the default run (positions, below)."""
    return pytest.param(name, *rest, marks=[pytest.mark.slow] if name in heavy else [])


@pytest.mark.parametrize("mode", ["fwd", pytest.param("rev", marks=pytest.mark.slow)])
@pytest.mark.parametrize("name", LEARN_COVERED)
def test_gradients_in_positions_and_parameters(small_sphere, name, mode):
    """Derivatives against finite differences, jointly in the positions and every
    continuous parameter: one compiled function per method, so one compile for the
    evaluations and one for the derivative.  Forward mode by default: the tuner
    differentiates the parameters, and SURE the positions, in forward mode; reverse
    mode with -m slow (and the kernel flow's in test_kernel_flow.py).  Guided filtering chooses patches by an
    argmin: on the jittered sphere near ties flip under finite-difference steps, so its
    positions are checked on a box (test_feature_denoise.py), its parameters here."""
    method = METHODS[name]
    params = method.continuous
    w = jax.random.normal(jax.random.PRNGKey(4), small_sphere.vertices.shape)
    # the loop body is what is differentiated (the learned stack has no iteration count to set)
    f = compiled(method, small_sphere, **({"iterations": 1} if "iterations" in method.params else {}))
    theta = tuple(jnp.asarray(float(method.defaults()[p])) for p in params)
    if name == "guided_normal":
        loss = jax.jit(lambda *t: jnp.sum(w * f(small_sphere.vertices, **dict(zip(params, t)))))
        args = theta
    else:
        loss = jax.jit(lambda x, *t: jnp.sum(w * f(x, **dict(zip(params, t)))))
        args = (small_sphere.vertices, *theta)
    check_grads(loss, args, order=1, modes=(mode,), atol=1e-5, rtol=1e-4, eps=FD_EPS.get(name))


@pytest.mark.slow   # each parameter alone, in each mode: the joint check above, taken apart
@pytest.mark.parametrize("name,param", [(n, p) for n in NAMES for p in METHODS[n].continuous])
@pytest.mark.parametrize("mode", ["fwd", "rev"])
def test_gradient_in_each_continuous_parameter(small_sphere, name, param, mode):
    method = METHODS[name]
    w = jax.random.normal(jax.random.PRNGKey(2), small_sphere.vertices.shape)
    base = method.defaults()[param]
    f = compiled(method, small_sphere, iterations=1)
    loss = jax.jit(lambda p: jnp.sum(w * f(small_sphere.vertices, **{param: p})))
    check_grads(loss, (jnp.asarray(float(base)),), order=1, modes=(mode,), atol=1e-5, rtol=1e-4)


@pytest.mark.parametrize("name", [_slow_if(("geometric", "cotangent_implicit"), n) for n in
                                  ["kernel", "taubin", "cotangent_implicit", "bilateral", "geometric"]])
def test_float32_gradients_are_finite_and_close_to_float64(small_sphere, name):
    method = METHODS[name]
    param = method.continuous[0]
    base = float(method.defaults()[param])
    w = jax.random.normal(jax.random.PRNGKey(5), small_sphere.vertices.shape)

    def grad(dtype):
        m = small_sphere.astype(dtype)
        f = compiled(method, m)
        return jax.jit(jax.grad(lambda p: jnp.sum(w.astype(dtype) * f(m.vertices, **{param: p}))))(
            jnp.asarray(base, dtype))

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
    f = compiled(METHODS[name], mesh)

    @jax.jit
    def output_and_gradient(x):        # of sum(out²): one compile for both
        out, pull = jax.vjp(f, x)
        return out, pull(2.0 * out)[0]

    out, grads = output_and_gradient(mesh.vertices)
    assert np.all(np.isfinite(np.asarray(out)))
    np.testing.assert_array_equal(out[6], mesh.vertices[6])   # isolated vertex stays put
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


def test_as_method_refuses_what_is_not_a_name_or_a_method():
    from jaxmesh.denoise import as_method

    assert as_method("umbrella_flow") is METHODS["umbrella_flow"]
    with pytest.raises(ValueError, match="unknown method 'laplacian'"):
        as_method("laplacian")
    assert_refused(as_method, 3, param="method", message="registry name or a Method", error=TypeError)


@pytest.mark.parametrize("method", ["taubin", pytest.param("guided_normal", marks=pytest.mark.slow)])   # 3 s
def test_a_non_finite_result_is_an_error_eagerly_under_jit_and_under_vmap(bumpy_grid, method):
    """``throw`` (the default): FloatingPointError eagerly; under jit, and under vmap where one
    batch element is non-finite, the equinox runtime error with the same words; throw=False
    returns the NaNs.  Finite inputs give the eager result."""
    aux = METHODS[method].prepare(bumpy_grid)
    y = np.asarray(bumpy_grid.vertices)
    bad = y.copy()
    bad[3, 0] = np.nan
    run = lambda x, **kw: denoise(bumpy_grid.with_vertices(x), method, **aux, **kw).vertices  # noqa: E731
    with pytest.raises(FloatingPointError, match=f"{method} produced non-finite coordinates"):
        run(jnp.asarray(bad))
    np.testing.assert_allclose(jax.jit(run)(jnp.asarray(y)), run(jnp.asarray(y)), rtol=1e-12, atol=1e-12)
    with pytest.raises(Exception, match=f"{method} produced non-finite coordinates"):
        jax.block_until_ready(jax.jit(run)(jnp.asarray(bad)))
    with pytest.raises(Exception, match=f"{method} produced non-finite coordinates"):
        jax.block_until_ready(jax.jit(jax.vmap(run))(jnp.stack([jnp.asarray(y), jnp.asarray(bad)])))
    quiet = jax.jit(jax.vmap(lambda x: run(x, throw=False)))(jnp.stack([jnp.asarray(y), jnp.asarray(bad)]))
    assert np.isfinite(quiet[0]).all() and np.isnan(quiet[1]).any()


def test_continuous_parameters_are_typed_for_the_type_hook(bumpy_grid):
    """Every continuous parameter of every registered method is annotated (``Scalar``: a number or a
    float array), so the suite's beartype hook refuses a string or an integer array; numbers, float
    arrays and tracers (jit, vmap over a parameter) pass."""
    import inspect as _inspect

    from conftest import TYPECHECKED
    from jaxmesh.denoise import taubin_smoothing

    for name, method in METHODS.items():
        fn = _inspect.unwrap(method.function.func if hasattr(method.function, "func") else method.function)
        hints = _inspect.signature(fn).parameters
        for p in method.continuous:
            assert hints[p].annotation == "Scalar", (name, p, hints[p].annotation)
    y = bumpy_grid.vertices
    want = taubin_smoothing(bumpy_grid, 0.5, iterations=2).vertices
    np.testing.assert_allclose(taubin_smoothing(bumpy_grid, jnp.asarray(0.5), iterations=2).vertices, want)
    np.testing.assert_allclose(jax.jit(lambda lam: taubin_smoothing(bumpy_grid, lam, iterations=2).vertices)(0.5), want)
    both = jax.vmap(lambda lam: taubin_smoothing(bumpy_grid.with_vertices(y), lam, iterations=2).vertices)
    np.testing.assert_allclose(both(jnp.asarray([0.5, 0.5]))[1], want)
    if not TYPECHECKED:
        pytest.skip("the annotations are checked only with the suite's jaxtyping hook")
    for bad in ("0.5", jnp.asarray(1, jnp.int32)):
        with pytest.raises(TypeError, match="parameter 'lam'"):
            taubin_smoothing(bumpy_grid, bad, iterations=2)

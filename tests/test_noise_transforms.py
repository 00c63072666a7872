"""Noise model and normalisation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmesh


def test_noise_scale_is_relative_to_mean_edge_length(spot):
    noisy = jaxmesh.add_noise(spot, 0.1, jax.random.PRNGKey(0))
    eta = np.asarray(noisy.vertices - spot.vertices)
    ell = float(jaxmesh.mean_edge_length(spot))
    assert eta.std() == pytest.approx(0.1 * ell, rel=0.03)
    assert abs(eta.mean()) < 0.01 * ell
    again = jaxmesh.add_noise(spot, 0.1, 0)
    np.testing.assert_array_equal(again.vertices, noisy.vertices)  # int seed == PRNGKey(seed)
    other = jaxmesh.add_noise(spot, 0.1, jax.random.PRNGKey(1))
    assert not np.allclose(other.vertices, noisy.vertices)
    absolute = jaxmesh.add_noise(spot, 0.01, 0, relative=False)
    assert np.asarray(absolute.vertices - spot.vertices).std() == pytest.approx(0.01, rel=0.03)


def test_noise_along_normals(spot):
    noisy = jaxmesh.add_noise(spot, 0.1, 3, along_normals=True)
    eta = noisy.vertices - spot.vertices
    n = jaxmesh.vertex_normals(spot, "area")
    np.testing.assert_allclose(jnp.cross(eta, n), 0, atol=1e-12)
    assert float(jnp.std(jnp.sum(eta * n, -1))) == pytest.approx(0.1 * float(jaxmesh.mean_edge_length(spot)), rel=0.05)


def test_noise_on_batches_is_independent_and_scaled_per_mesh(tetra):
    b = tetra.with_vertices(jnp.stack([tetra.vertices, 1000.0 * tetra.vertices]))
    noisy = jaxmesh.add_noise(b, 0.1, 0)
    eta = np.asarray(noisy.vertices - b.vertices)
    assert eta[1].std() > 100 * eta[0].std()


def test_normalize(spot):
    big = spot.with_vertices(1000.0 * spot.vertices + 7.0)
    n, c, s = jaxmesh.normalize(big, return_transform=True)
    np.testing.assert_allclose(jaxmesh.bounding_box_diagonal(n), 1.0)
    np.testing.assert_allclose(jnp.max(n.vertices, 0) + jnp.min(n.vertices, 0), 0, atol=1e-12)
    np.testing.assert_allclose(n.vertices * s + c[None], big.vertices, rtol=1e-12)
    np.testing.assert_allclose(jaxmesh.normalize(spot).vertices, n.vertices, atol=1e-12)
    point = spot.with_vertices(jnp.zeros_like(spot.vertices) + 2.0)
    np.testing.assert_array_equal(jaxmesh.normalize(point).vertices, 0.0)  # no 0/0


def test_impulsive_noise_moves_a_fraction_along_the_normals(spot):
    ell = float(jaxmesh.mean_edge_length(spot))
    n = jaxmesh.vertex_normals(spot, "area")
    noisy = jaxmesh.add_impulsive_noise(spot, 0.5, 4, fraction=0.3)
    eta = np.asarray(noisy.vertices - spot.vertices)
    moved = np.linalg.norm(eta, axis=1) > 0
    # Bernoulli(0.3) per vertex: within 4 standard deviations of p V
    nv = spot.num_vertices
    assert abs(moved.sum() - 0.3 * nv) < 4 * np.sqrt(0.3 * 0.7 * nv)
    np.testing.assert_allclose(np.cross(eta, np.asarray(n)), 0, atol=1e-12)   # along the normals
    xi = np.sum(eta * np.asarray(n), axis=1)[moved]
    assert xi.std() == pytest.approx(0.5 * ell, rel=0.08)
    # the same key's full-fraction noise moves the chosen vertices by the same amount
    full = jaxmesh.add_noise(spot, 0.5, 4, along_normals=True)
    np.testing.assert_array_equal(noisy.vertices[moved], full.vertices[moved])
    np.testing.assert_array_equal(noisy.vertices[~moved], spot.vertices[~moved])
    # fraction 1 is the Gaussian model exactly, fraction 0 moves nothing
    np.testing.assert_array_equal(jaxmesh.add_noise(spot, 0.5, 4, along_normals=True, fraction=1.0).vertices,
                                  full.vertices)
    np.testing.assert_array_equal(jaxmesh.add_impulsive_noise(spot, 0.5, 4, fraction=0.0).vertices,
                                  spot.vertices)
    with pytest.raises(ValueError, match="fraction"):
        jaxmesh.add_noise(spot, 0.5, 4, fraction=1.5)


def test_impulsive_noise_is_jittable_in_the_fraction_and_differentiable_in_sigma(spot):
    f = jax.jit(lambda p, s: jaxmesh.add_noise(spot, s, 2, along_normals=True, fraction=p).vertices)
    np.testing.assert_allclose(f(0.4, 0.3), jaxmesh.add_impulsive_noise(spot, 0.3, 2, fraction=0.4).vertices,
                               rtol=0, atol=1e-14)
    g = jax.grad(lambda s: jnp.sum(jaxmesh.add_impulsive_noise(spot, s, 2, fraction=0.4).vertices ** 2))(0.3)
    h = 1e-6
    fd = (jnp.sum(f(0.4, 0.3 + h) ** 2) - jnp.sum(f(0.4, 0.3 - h) ** 2)) / (2 * h)
    assert float(g) == pytest.approx(float(fd), rel=1e-6)


def _with_far(mesh, index=0, value=1e30):
    v = np.asarray(mesh.vertices, np.float64).copy()
    v[index, 0] = value
    return mesh.with_vertices(v)


def test_far_vertices_leave_the_frame_and_the_rest_keeps_it(spot):
    """A corrupt coordinate (1e30) is far (host and traced tests agree, batched too); the
    frame is the box of the others, exactly the frame of the mesh without it, and an
    ordinary mesh's frame is its plain box.  In float32, where the plain diagonal of such a
    box overflows, the scale stays finite."""
    from jaxmesh.transforms import far_mask, far_vertices, unit_frame

    v = np.asarray(spot.vertices, np.float64)
    c, s = unit_frame(spot)
    np.testing.assert_array_equal(c, 0.5 * (v.max(0) + v.min(0)))
    assert float(s) == float(np.sqrt(np.sum((v.max(0) - v.min(0)) ** 2)))
    far = _with_far(spot, 5)
    np.testing.assert_array_equal(far_vertices(far), [5])
    np.testing.assert_array_equal(np.flatnonzero(np.asarray(far_mask(far))), [5])
    np.testing.assert_array_equal(np.flatnonzero(np.asarray(jax.jit(far_mask)(far))), [5])
    rest = np.delete(v, 5, axis=0)
    cf, sf = unit_frame(far)
    np.testing.assert_allclose(cf, 0.5 * (rest.max(0) + rest.min(0)), rtol=1e-15)
    np.testing.assert_allclose(sf, np.linalg.norm(rest.max(0) - rest.min(0)), rtol=1e-15)
    both = spot.with_vertices(jnp.stack([spot.vertices, far.vertices]))
    mask = np.asarray(far_mask(both))
    assert mask.shape == (2, spot.num_vertices) and not mask[0].any() and np.flatnonzero(mask[1]).tolist() == [5]
    assert far_vertices(spot).size == 0
    big = spot.with_vertices(jnp.asarray(1e20 * v, jnp.float32))      # 1e20² overflows float32
    c32, s32 = unit_frame(big)
    assert np.isfinite(np.asarray(s32)) and float(s32) == pytest.approx(1e20 * float(s), rel=1e-5)


@pytest.mark.filterwarnings("ignore::jaxmesh.mesh.MeshWarning")
def test_a_far_vertex_is_refused_or_named_never_a_silent_wreck(spot):
    """Denoising a mesh with a 1e30 coordinate is an error naming the vertex where the method
    spreads it over its neighbours (the box of the others grows), and otherwise leaves the others
    as the method would; the blind default and the codec refuse it up front.
    Before, in float32 the frame's scale overflowed and the output was NaN without an error; in
    float64 every other vertex moved by up to 1e12 diagonals."""
    from jaxmesh.denoise import denoise_in_unit_frame
    from jaxmesh.tune import choose_denoiser

    far = _with_far(spot, 3)
    for dtype in (np.float64, np.float32):
        cast = far.with_vertices(jnp.asarray(far.vertices, dtype))
        with pytest.raises(FloatingPointError, match="vertex 3 lies far from the rest"):
            denoise_in_unit_frame(cast, "taubin")
    with pytest.raises(FloatingPointError, match="vertex 3 lies far"):     # float32: its normals overflow
        denoise_in_unit_frame(far.with_vertices(jnp.asarray(far.vertices, np.float32)), "bilateral")
    # in float64 a normal filter moves vertices along the normals of their own faces: in the
    # robust frame the others are denoised as usual (before: every vertex moved by 1e12 diagonals)
    out = np.asarray(denoise_in_unit_frame(far, "bilateral").vertices, np.float64)
    moved = np.delete(np.linalg.norm(out - np.asarray(far.vertices), axis=1), 3)
    assert np.all(moved < 0.05 * float(jaxmesh.bounding_box_diagonal(spot))), moved.max()
    with pytest.raises(ValueError, match="vertex 3 lies far from the rest"):
        choose_denoiser(far)
    with pytest.raises(ValueError, match="vertex 3 lies far .*quantization step"):
        jaxmesh.compress.compress(far)
    with pytest.raises(FloatingPointError, match="diverged .*smaller step"):     # no far vertex: the usual hint
        denoise_in_unit_frame(_with_far(spot, 3, np.nan), "taubin")


def test_denoise_in_unit_frame_compiled_agrees_with_the_eager_framed_run(spot):
    """denoise_in_unit_frame runs framed_run as one compiled program (a registered method by
    name, a caller's own Method by identity, the continuous parameters traced): the same output
    as framed_run called eagerly, one primitive at a time; the parameters are still checked on
    their concrete values, so a bad value is an error naming it and Taubin without a pass band
    still warns."""
    from jaxmesh.denoise import METHODS, Method, denoise_in_unit_frame
    from jaxmesh.denoise import framed
    from jaxmesh.denoise.framed import framed_run
    from jaxmesh.mesh import MeshWarning

    noisy = jaxmesh.add_noise(spot, 0.3, 0)
    mine = Method("mine", METHODS["taubin"].function, METHODS["taubin"].params, "Taubin, unregistered", "")
    cases = (("taubin", {"lam": 0.4, "mu": -0.42, "iterations": 7}), ("kernel", {"lam": 0.3, "iterations": 2}),
             ("kernel", {"lam": 0.2, "iterations": 2, "variant": "paper"}), (mine, {"iterations": 3}))
    programs = framed._method_program._cache_size()
    for method, params in cases:
        want, bad = framed_run(noisy, method, **params)
        got = denoise_in_unit_frame(noisy, method, **params)
        assert not bool(bad)
        np.testing.assert_allclose(np.asarray(got.vertices), np.asarray(want.vertices), rtol=0, atol=1e-12)
        assert np.abs(np.asarray(got.vertices - noisy.vertices)).max() > 1e-4     # it did denoise
    assert framed._method_program._cache_size() > programs     # programs were compiled: no eager run
    with pytest.warns(MeshWarning, match="not a low-pass filter"):
        denoise_in_unit_frame(noisy, "taubin", lam=0.5, mu=-0.3)
    with pytest.raises(ValueError, match="taubin: lam must be a finite number"):
        denoise_in_unit_frame(noisy, "taubin", lam=-1.0)
    with pytest.raises(ValueError, match="iterations must be a non-negative int"):
        denoise_in_unit_frame(noisy, "kernel", iterations=2.5)


def test_progress_reports_every_iteration_before_and_after_compiled_calls(spot):
    """A progress callback sees each outer iteration whether or not a compiled program of the
    same call is kept (one traced outside the context must not be reused inside it, and one
    traced inside must not call a stale callback later)."""
    from jaxmesh.denoise import denoise_in_unit_frame, progress

    noisy = jaxmesh.add_noise(spot, 0.3, 0)
    seen = []
    with progress(seen.append):
        first = denoise_in_unit_frame(noisy, "taubin", iterations=4)
    assert seen == [0, 1, 2, 3]
    plain = denoise_in_unit_frame(noisy, "taubin", iterations=4)     # compiled, no callback
    assert seen == [0, 1, 2, 3]
    again = []
    with progress(again.append):
        denoise_in_unit_frame(noisy, "taubin", iterations=4)
    assert again == [0, 1, 2, 3] and seen == [0, 1, 2, 3]
    np.testing.assert_allclose(np.asarray(plain.vertices), np.asarray(first.vertices), rtol=0, atol=1e-12)


def test_host_built_inputs_are_kept_per_connectivity(spot, monkeypatch):
    """A compiled call's host-built inputs (the face graph) are built once per connectivity:
    new positions on the same faces reuse them, other faces of the same sizes (or a copy of the
    mesh with two faces swapped) build their own, an input over HOST_BUILT_MAX_BYTES is not kept,
    and the output equals a call given a freshly built graph."""
    from jaxmesh.denoise import METHODS, _compiled
    from jaxmesh.denoise.face_graph import face_graph

    calls = []

    def counting(mesh):
        calls.append(mesh.num_faces)
        return face_graph(mesh)

    noisy = jaxmesh.add_noise(spot, 0.3, 0)
    _compiled.forget_host_built()
    first = _compiled.host_built(counting, noisy)
    assert _compiled.host_built(counting, jaxmesh.add_noise(spot, 0.3, 1)) is first and len(calls) == 1
    f = np.asarray(spot.faces)
    swapped = jaxmesh.Mesh.from_arrays(np.asarray(spot.vertices), f[np.r_[1, 0, 2:len(f)]])
    assert _compiled.connectivity_key(swapped) != _compiled.connectivity_key(spot)
    other = _compiled.host_built(counting, swapped)
    assert len(calls) == 2 and other is not first
    np.testing.assert_array_equal(np.asarray(other.ring[:2]), np.asarray(face_graph(swapped).ring[:2]))
    assert _compiled.host_built(counting, noisy) is not first and len(calls) == 3     # one entry per builder
    monkeypatch.setattr(_compiled, "HOST_BUILT_MAX_BYTES", 1000)              # too large to keep: built again
    _compiled.host_built(counting, swapped)
    _compiled.host_built(counting, swapped)
    assert len(calls) == 5
    monkeypatch.undo()
    _compiled.forget_host_built()
    kept = METHODS["bilateral_normal"](noisy, iterations=2)
    again = METHODS["bilateral_normal"](noisy, iterations=2)       # the kept graph
    given = METHODS["bilateral_normal"](noisy, iterations=2, graph=face_graph(noisy))
    np.testing.assert_array_equal(np.asarray(again.vertices), np.asarray(kept.vertices))
    np.testing.assert_array_equal(np.asarray(given.vertices), np.asarray(kept.vertices))


def test_taubin_pass_band_warning_names_the_callers_line(spot):
    """The warning for μ > −λ points at the user's call, whether the call runs compiled,
    framed, or op by op under ``jax.disable_jit()``: not at a line inside the library."""
    from jaxmesh.denoise import METHODS, denoise_in_unit_frame
    from jaxmesh.mesh import MeshWarning

    calls = (lambda: METHODS["taubin"](spot, lam=0.5, mu=-0.3, iterations=1),
             lambda: denoise_in_unit_frame(spot, "taubin", lam=0.5, mu=-0.3, iterations=1))
    for call in calls:
        for eager in (False, True):
            with pytest.warns(MeshWarning, match="not a low-pass filter") as record, jax.disable_jit(eager):
                call()
            got = [(w.filename, w.lineno) for w in record if "low-pass" in str(w.message)]
            assert got and all(f == __file__ for f, _ in got), (eager, got)


def test_eager_calls_compile_one_program_each_not_one_per_host_array():
    """A host array reaches the device by ``device_put`` (``jnp.asarray`` compiles a program for
    each new shape), an int seed becomes a key inside the noise program, and the divergence test
    is one program: counted by JAX's compile events on a mesh of a shape no other test uses."""
    from conftest import grid_arrays
    from jaxmesh.denoise.divergence import diverged

    v, f = grid_arrays(13, 7, jitter=0.1, seed=3)
    mesh = jaxmesh.Mesh.from_arrays(v, f)
    moved = np.asarray(mesh.vertices) * 1.5
    compiled = []

    def listen(name, secs, **kw):
        if name.endswith("backend_compile_duration"):
            compiled.append(name)

    def programs(run):
        compiled.clear()
        jax.monitoring.register_event_duration_secs_listener(listen)
        try:
            out = run()
        finally:
            jax.monitoring.unregister_event_duration_listener(listen)
        return len(compiled), out

    assert programs(lambda: mesh.with_vertices(moved))[0] == 0
    count, noisy = programs(lambda: jaxmesh.add_noise(mesh, 0.3, 11))
    assert count == 1
    np.testing.assert_array_equal(noisy.vertices, jaxmesh.add_noise(mesh, 0.3, jax.random.PRNGKey(11)).vertices)
    count, bad = programs(lambda: diverged(mesh, mesh.with_vertices(moved * 20)))
    assert count == 1 and bool(bad)
    count, err = programs(lambda: jaxmesh.metrics.rms_vertex_error(mesh, moved))
    assert count == 1 and float(err) > 0


def test_library_keys_and_method_parameters_cost_no_eager_programs():
    """An int seed's library key (stream and salt folded in) is one program, equal to folding
    ``PRNGKey(seed)`` op by op; a method's host-number parameters stay host arrays (traced as
    arguments, no cast program), values given as JAX arrays stay JAX arrays."""
    from jaxmesh._private import library_key
    from jaxmesh.denoise import METHODS

    compiled = []

    def listen(name, secs, **kw):
        if name.endswith("backend_compile_duration"):
            compiled.append(name)
    jax.monitoring.register_event_duration_secs_listener(listen)
    try:
        key = library_key(11, 12345, salt=678)
    finally:
        jax.monitoring.unregister_event_duration_listener(listen)
    assert len(compiled) == 1
    expected = jax.random.fold_in(jax.random.fold_in(jax.random.PRNGKey(11), 12345), 678)
    np.testing.assert_array_equal(key, expected)
    np.testing.assert_array_equal(library_key(jax.random.PRNGKey(11), 12345),
                                  jax.random.fold_in(jax.random.PRNGKey(11), 12345))
    cont, _ = METHODS["taubin"].split(lam=0.5, mu=-1)
    assert all(isinstance(v, np.ndarray) and v.dtype == jnp.result_type(float) for v in cont.values())
    cont, _ = METHODS["taubin"].split(lam=jnp.asarray(0.5), mu=-0.53)
    assert isinstance(cont["lam"], jax.Array) and isinstance(cont["mu"], np.ndarray)

"""jaxmesh._exported: a stored program gives what jax.jit gives, a later process (a fresh
wrapper) loads it without tracing, damaged files are refused, and anything the store cannot
hold falls back to tracing."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxmesh import _exported
from jaxmesh.mesh import Mesh


def _body(traces: list):
    def fun(mesh: Mesh, x, params: dict, count, scale, method: str, statics: tuple):
        traces.append(method)
        y = x * params["w"] + jnp.sum(mesh.vertices) * scale
        y = y if count is None else y + count.astype(y.dtype)
        return y * dict(statics)["k"], jnp.sum(y)
    return fun


@pytest.fixture
def store(tmp_path):
    _exported.set_store(tmp_path / "exported")
    yield tmp_path / "exported"
    _exported.set_store(None)


def _args(tetra):
    x = tetra.vertices + 0.5
    return (tetra, x, {"w": jnp.asarray(np.arange(4.0)[:, None])}, None, 0.25), dict(method="a", statics=(("k", 3),))


def test_a_stored_program_gives_what_jit_gives_and_a_fresh_wrapper_loads_it_untraced(tetra, store):
    args, statics = _args(tetra)
    traces: list = []
    expected = jax.jit(_body([]), static_argnames=("method", "statics"))(*args, **statics)
    first = _exported.stored_jit(_body(traces), static_argnames=("method", "statics"))
    got = first(*args, **statics)
    assert len(traces) == 1 and len(list(store.iterdir())) == 1
    for a, b in zip(got, expected):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    first(*args, **statics)
    assert len(traces) == 1                                  # the in-process program is reused
    fresh_traces: list = []
    fresh = _exported.stored_jit(_body(fresh_traces), static_argnames=("method", "statics"))
    again = fresh(*args, **statics)
    assert fresh_traces == []                                # loaded from the store, not traced
    for a, b in zip(again, expected):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    # another static value, another dtype or another structure: another program
    fresh(*args, method="b", statics=(("k", 3),))
    fresh(*args[:3], jnp.asarray(2, jnp.int32), 0.25, **statics)
    assert fresh_traces == ["b", "a"] and len(list(store.iterdir())) == 3


def test_a_damaged_or_foreign_file_is_removed_and_the_function_traced(tetra, store):
    args, statics = _args(tetra)
    expected = _exported.stored_jit(_body([]), static_argnames=("method", "statics"))(*args, **statics)
    (path,) = store.iterdir()
    data = bytearray(path.read_bytes())
    data[-5] ^= 0xFF
    path.write_bytes(bytes(data))
    traces: list = []
    got = _exported.stored_jit(_body(traces), static_argnames=("method", "statics"))(*args, **statics)
    assert traces == ["a"]                                   # the damaged file was not used
    np.testing.assert_array_equal(np.asarray(got[0]), np.asarray(expected[0]))
    path.write_bytes(b"not a program")
    traces.clear()
    _exported.stored_jit(_body(traces), static_argnames=("method", "statics"))(*args, **statics)
    assert traces == ["a"] and path.read_bytes()[:len(_exported._MAGIC)] == _exported._MAGIC   # rewritten


def test_what_the_store_cannot_hold_is_traced_as_by_jit(tetra, store):
    calls: list = []

    def returns_a_mesh(mesh: Mesh, x):
        calls.append(1)
        return mesh.with_vertices(x)                         # a custom pytree out: not serialisable

    f = _exported.stored_jit(returns_a_mesh)
    out = f(tetra, tetra.vertices * 2)
    assert isinstance(out, Mesh) and list(store.iterdir()) == []
    np.testing.assert_array_equal(np.asarray(out.vertices), np.asarray(tetra.vertices) * 2)
    # inside another transformation the function is traced with it (vmap, grad)
    g = _exported.stored_jit(lambda x, s: jnp.sum(jnp.sin(x)) * s)
    xs = jnp.linspace(0.0, 1.0, 6).reshape(2, 3)
    np.testing.assert_allclose(np.asarray(jax.vmap(g, in_axes=(0, None))(xs, 2.0)),
                               np.sum(np.sin(np.asarray(xs)), axis=1) * 2, rtol=1e-12)
    np.testing.assert_allclose(np.asarray(jax.grad(g)(xs[0], 2.0)), np.cos(np.asarray(xs[0])) * 2, rtol=1e-12)
    # no store: plain jit, nothing written
    _exported.set_store(None)
    h = _exported.stored_jit(lambda x: x + 1)
    np.testing.assert_array_equal(np.asarray(h(jnp.ones(3))), np.full(3, 2.0))


def test_the_store_keeps_at_most_its_limit_and_the_newest(tmp_path, monkeypatch):
    monkeypatch.setattr(_exported, "STORE_MAX_FILES", 4)
    _exported.set_store(tmp_path)
    try:
        f = _exported.stored_jit(lambda x: x * 2)
        counts = []
        for n in range(1, 8):
            f(jnp.ones(n))
            counts.append(len(list(tmp_path.glob("*.jaxexport"))))
        assert counts == [1, 2, 3, 4, 3, 4, 3]          # past 4, down to 3 (the newest among them)
        traces: list = []
        g = _exported.stored_jit(lambda x: traces.append(1) or x * 2)
        g(jnp.ones(7))
        assert traces == []                              # the newest program was kept
    finally:
        _exported.set_store(None)


def test_a_cache_folder_that_cannot_hold_the_store_leaves_it_off(tmp_path, monkeypatch):
    from jaxmesh import compiler

    monkeypatch.setattr(jax.config, "update", lambda *args: None)   # JAX's own cache settings left alone
    (tmp_path / compiler.EXPORTED_FOLDER).write_text("a file where the folder goes")
    with pytest.warns(UserWarning, match="not kept"):
        assert compiler.enable_compilation_cache(tmp_path) == tmp_path
    assert _exported.store_path() is None

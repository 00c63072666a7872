"""jaxmesh._threads: the map's results are the loop's, in order; errors reach the caller;
the workers see the caller's x64 setting; JAXMESH_THREADS is honoured and checked."""

import threading

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxmesh import _threads


@jax.jit
def _work(x):
    return jax.lax.fori_loop(0, 50, lambda _, y: jnp.sin(y) + 0.5 * y, x)


def test_the_map_is_the_loop_in_order(monkeypatch):
    monkeypatch.setenv("JAXMESH_THREADS", "3")
    items = [jnp.linspace(0.0, float(k), 1000) for k in range(7)]
    names: set = set()

    def fn(x):
        names.add(threading.current_thread().name)
        return np.asarray(_work(x))

    got = _threads.concurrent_map(fn, items)
    for a, x in zip(got, items):
        np.testing.assert_array_equal(a, np.asarray(_work(x)))
    assert any(n.startswith("jaxmesh-map") for n in names)
    assert _threads.concurrent_map(fn, []) == []


def test_errors_reach_the_caller_and_one_thread_stays_in_the_caller(monkeypatch):
    monkeypatch.setenv("JAXMESH_THREADS", "2")

    def fn(k):
        if k == 3:
            raise ValueError("item 3")
        return k

    with pytest.raises(ValueError, match="item 3"):
        _threads.concurrent_map(fn, range(5))
    monkeypatch.setenv("JAXMESH_THREADS", "1")
    assert _threads.concurrent_map(lambda _: threading.current_thread(), range(3)) == [threading.current_thread()] * 3
    monkeypatch.setenv("JAXMESH_THREADS", "two")
    with pytest.raises(ValueError, match="JAXMESH_THREADS"):
        _threads.concurrent_map(fn, range(2))


def test_the_workers_take_the_callers_x64_setting(monkeypatch):
    monkeypatch.setenv("JAXMESH_THREADS", "2")
    enable = getattr(jax, "enable_x64", None)
    if enable is None:
        pytest.skip("this JAX has no jax.enable_x64 context")
    with enable(False):
        dtypes = _threads.concurrent_map(lambda _: jnp.asarray(1.0).dtype, range(4))
    assert dtypes == [jnp.float32] * 4
    assert _threads.concurrent_map(lambda _: jnp.asarray(1.0).dtype, range(4)) == [jnp.float64] * 4

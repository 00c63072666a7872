"""The host mirror (jaxmesh.host): its matrices against independent references, and the
blind chooser building each host matrix once."""

from __future__ import annotations

import collections
import importlib

import jax.numpy as jnp
import numpy as np
import pytest
import scipy.sparse.csgraph as csgraph
import trimesh

import jaxmesh
import jaxmesh.sparse
from conftest import grid_arrays
from jaxmesh.host import HostMesh, as_host
from jaxmesh.tune import Candidate, choose_denoiser


@pytest.fixture(scope="module")
def ball():
    s = trimesh.creation.icosphere(4)                       # 2562 vertices
    return jaxmesh.Mesh.from_arrays(s.vertices, s.faces).astype(jnp.float64)


def dense_umbrella(faces: np.ndarray, n: int) -> np.ndarray:
    a = np.zeros((n, n))
    for tri in faces:
        for k in range(3):
            a[tri[k], tri[(k + 1) % 3]] = a[tri[(k + 1) % 3], tri[k]] = 1
    d = a.sum(1)
    return np.where(d[:, None] > 0, a / np.where(d > 0, d, 1)[:, None], 0) - np.diag(d > 0)


def test_the_matrices_equal_their_references():
    """On a jittered grid with one isolated vertex: A, the two-ring (hop distances 1–2 from
    scipy's breadth-first search), K and ‖row_i(K²)‖ from a dense numpy loop."""
    v, f = grid_arrays(5, 4, jitter=0.1)
    v = np.vstack([v, [[9.0, 9.0, 0.0]]])
    mesh = jaxmesh.Mesh.from_arrays(v, f, warn=False)
    host = HostMesh(mesh)
    k = dense_umbrella(f, len(v))
    np.testing.assert_array_equal(host.adjacency.toarray(), (k - np.diag(np.diag(k)) != 0).astype(float))
    hops = csgraph.shortest_path(host.adjacency, unweighted=True)
    np.testing.assert_array_equal(host.two_ring.toarray(), ((hops >= 1) & (hops <= 2)).astype(float))
    np.testing.assert_allclose(host.umbrella.toarray(), k, atol=1e-15)
    np.testing.assert_allclose(host.umbrella_square_row_norms, np.linalg.norm(k @ k, axis=1), rtol=1e-13)
    assert host.umbrella_square_row_norms[-1] == 0


def test_each_value_is_built_once_and_the_face_graph_is_shared(tetra):
    host = as_host(tetra)
    assert as_host(host) is host
    assert host.umbrella_square is host.umbrella_square and host.two_ring is host.two_ring
    calls = []
    assert host.memo("x", lambda: calls.append(1) or 5) == 5 and host.memo("x", lambda: calls.append(1) or 6) == 5
    assert calls == [1]
    guided, bilateral = host.aux("guided_normal"), host.aux("bilateral_normal")
    assert guided["graph"] is bilateral["graph"] and host.aux("taubin")["rings"] is host.aux("hc")["rings"]
    assert host.aux("geometric") == {}
    np.testing.assert_array_equal(guided["graph"].ring, jaxmesh.denoise.face_graph(tetra).ring)


def test_a_host_mesh_refuses_what_is_not_one_mesh(tetra):
    with pytest.raises(TypeError, match="parameter 'mesh'|takes a jaxmesh.Mesh"):   # the type hook's, or ours
        HostMesh(np.zeros((4, 3)))
    with pytest.raises(ValueError, match="takes one mesh"):
        HostMesh(tetra.with_vertices(jnp.stack([tetra.vertices] * 2)))


def _count_builds(monkeypatch) -> collections.Counter:
    """Count the builds of K, A, the face graph's tiers and the projection normals."""
    counts = collections.Counter()
    modules = (jaxmesh.sparse, jaxmesh.sparse, importlib.import_module("jaxmesh.denoise.face_graph"),
               importlib.import_module("jaxmesh.tune.noise_level"))
    for module, name in zip(modules, ("umbrella_matrix", "adjacency_matrix", "_tiers", "_projection_normals")):
        def counted(*args, _f=getattr(module, name), _name=name, **kwargs):
            counts[_name] += 1
            return _f(*args, **kwargs)
        monkeypatch.setattr(module, name, counted)
    return counts


def test_one_blind_choice_builds_each_host_matrix_once(ball, monkeypatch):
    """Gaussian noise: the impulsive reading, σ̂, σ̂_t, the pilot, the ranking and the choice share
    one K, one A, one face graph and one projection-normal field (they were built 3, 2, 3 and 3 times)."""
    counts = _count_builds(monkeypatch)
    result = choose_denoiser(jaxmesh.add_noise(ball, 0.3, 4), candidates=[Candidate("bilateral_normal", {})],
                             paths=(), blend_draws=0)
    assert result.noise_law == "gaussian"
    assert dict(counts) == {"umbrella_matrix": 1, "adjacency_matrix": 1, "_tiers": 1, "_projection_normals": 1}


@pytest.mark.slow   # a whole impulsive search (impulse repair, the held-out estimate)
def test_one_impulsive_choice_builds_each_host_matrix_once(ball, monkeypatch):
    counts = _count_builds(monkeypatch)
    result = choose_denoiser(jaxmesh.add_impulsive_noise(ball, 0.5, 3, fraction=0.5),
                             candidates=[Candidate("bilateral_normal", {})],
                             impulsive_candidates=[Candidate("impulse_repair", {"iterations": 1})], paths=(),
                             blend_draws=0)
    assert result.noise_law == "impulsive"
    assert dict(counts) == {"umbrella_matrix": 1, "_tiers": 1, "_projection_normals": 1}


def test_the_estimators_read_a_host_mesh_as_its_mesh(ball):
    """σ̂ (every estimator), σ̂_t and the impulsive reading are the same from the Mesh and from its
    HostMesh, and a second reading on the same HostMesh builds nothing again."""
    from jaxmesh.tune import estimate_impulsive_noise, estimate_noise, estimate_tangential_noise

    noisy = jaxmesh.add_noise(ball, 0.01, 2)
    host = HostMesh(noisy)
    for method in ("min", "flat", "umbrella", "quadric"):
        assert estimate_noise(host, method) == estimate_noise(noisy, method)
    assert estimate_tangential_noise(host) == estimate_tangential_noise(noisy)
    assert estimate_impulsive_noise(host).fraction == estimate_impulsive_noise(noisy).fraction
    kept = dict(host.__dict__)
    estimate_noise(host)
    assert all(host.__dict__[k] is v for k, v in kept.items() if k != "_memo")

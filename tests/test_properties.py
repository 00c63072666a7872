"""Properties on random valid meshes drawn by hypothesis: the operators agree with
their sparse matrices, rows of K sum to 0, L is symmetric, nothing is NaN,
and translation / rotation invariances hold where they should."""

import jax.numpy as jnp
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jaxmesh
from jaxmesh import operators as O
from jaxmesh import sparse as S


@st.composite
def random_meshes(draw):
    n_v = draw(st.integers(4, 12))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    v = rng.standard_normal((n_v, 3)) * draw(st.sampled_from([1e-3, 1.0, 1e3]))
    n_f = draw(st.integers(1, 2 * n_v))
    f = np.array([rng.choice(n_v, 3, replace=False) for _ in range(n_f)])
    return jaxmesh.Mesh.from_arrays(v, f, warn=False)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(random_meshes())
def test_operator_properties(mesh):
    x = mesh.vertices
    for name, op in [("umbrella_matrix", O.umbrella), ("laplacian_matrix", O.laplacian),
                     ("normalized_laplacian_matrix", O.normalized_laplacian),
                     ("cotangent_laplacian_matrix", O.cotangent_laplacian)]:
        y = op(mesh, x)
        assert np.isfinite(np.asarray(y)).all()
        np.testing.assert_allclose(getattr(S, name)(mesh) @ np.asarray(x), y, rtol=1e-9,
                                   atol=1e-9 * float(jnp.max(jnp.abs(y)) + 1))
    k = S.umbrella_matrix(mesh)
    np.testing.assert_allclose(np.asarray(k.sum(axis=1)).ravel(), 0, atol=1e-12)
    lap = S.laplacian_matrix(mesh)
    assert abs(lap - lap.T).max() == 0
    # translation invariance of the umbrella / Laplacian / cotangent weights, rotation of areas
    t = jnp.array([3.0, -2.0, 1.0]) * float(jaxmesh.bounding_box_diagonal(mesh))
    moved = mesh.with_vertices(x + t)
    scale = float(jnp.max(jnp.abs(x))) + float(jnp.max(jnp.abs(t)))
    np.testing.assert_allclose(O.umbrella(moved, moved.vertices), O.umbrella(mesh, x), atol=1e-10 * scale)
    q, _ = np.linalg.qr(np.random.default_rng(0).standard_normal((3, 3)))
    rot = mesh.with_vertices(x @ jnp.asarray(q).T)
    np.testing.assert_allclose(jaxmesh.face_areas(rot), jaxmesh.face_areas(mesh), rtol=1e-9,
                               atol=1e-12 * float(jnp.max(jaxmesh.face_areas(mesh))))
    for arr in (jaxmesh.vertex_normals(mesh), O.cotangent_weights(mesh), O.laplace_beltrami(mesh, x)):
        assert np.isfinite(np.asarray(arr)).all()

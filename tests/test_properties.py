"""Properties on random valid meshes drawn by hypothesis (isolated vertices,
non-manifold edges and near-degenerate faces included): the operators agree with
their sparse matrices, rows of K sum to 0, L is symmetric, nothing is NaN, and under
a rigid motion x -> R x + t the intrinsic quantities (cotangent and Laplace–Beltrami
weights, areas) are unchanged while the vector quantities rotate
(umbrella Δx, Laplace–Beltrami Δ_m x, vertex normals: f(Rx + t) = R f(x))."""

import jax
import jax.numpy as jnp
import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import jaxmesh
from jaxmesh import operators as O
from jaxmesh import sparse as S

# a few (vertices, faces) sizes, so the operators compile a few times, not once per example
SIZES = [(4, 1), (6, 5), (12, 16), (12, 24)]


@st.composite
def random_meshes(draw):
    n_v, n_f = draw(st.sampled_from(SIZES))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    v = rng.standard_normal((n_v, 3)) * draw(st.sampled_from([1e-3, 1.0, 1e3]))
    f = np.array([rng.choice(n_v, 3, replace=False) for _ in range(n_f)])
    return jaxmesh.Mesh.from_arrays(v, f, warn=False)


@st.composite
def rigid_motions(draw):
    seed = draw(st.integers(0, 2**31 - 1))
    q, r = np.linalg.qr(np.random.default_rng(seed).standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))                  # a uniform rotation or reflection ...
    if np.linalg.det(q) < 0:                     # ... made a rotation (normals flip under reflections)
        q[:, 0] = -q[:, 0]
    t = np.random.default_rng(seed + 1).standard_normal(3) * draw(st.sampled_from([0.0, 1.0, 3.0]))
    return q, t


@jax.jit
def _quantities(mesh):
    x = mesh.vertices
    return {"cotangent_weights": O.cotangent_weights(mesh),
            "laplace_beltrami_weights": O.laplace_beltrami_weights(mesh),
            "areas": jaxmesh.face_areas(mesh),
            "umbrella": O.umbrella(mesh, x),
            "laplace_beltrami": O.laplace_beltrami(mesh, x),
            "normals": jaxmesh.vertex_normals(mesh)}


@jax.jit
def _operators(mesh):
    """Each operator applied to the positions, one compiled program per mesh shape."""
    x = mesh.vertices
    return {"umbrella_matrix": O.umbrella(mesh, x), "laplacian_matrix": O.laplacian(mesh, x),
            "normalized_laplacian_matrix": O.normalized_laplacian(mesh, x),
            "cotangent_laplacian_matrix": O.cotangent_laplacian(mesh, x)}


def _well_conditioned_normals(mesh, ratio=1e-6):
    """Vertices whose area-weighted sum of face normals is not a cancellation:
    |Σ a_t n_t| > ratio Σ a_t (else normalising it amplifies rounding into an
    arbitrary direction, or exactly zero, in either frame)."""
    v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])     # 2 a_t n_t
    summed, total = np.zeros_like(v), np.zeros(len(v))
    for k in range(3):
        np.add.at(summed, f[:, k], cross)
        np.add.at(total, f[:, k], np.linalg.norm(cross, axis=1))
    return np.linalg.norm(summed, axis=1) > ratio * total


SCALARS = ("cotangent_weights", "laplace_beltrami_weights", "areas")
VECTORS = ("umbrella", "laplace_beltrami", "normals")


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(random_meshes(), rigid_motions())
def test_operator_properties(mesh, motion):
    x = mesh.vertices
    applied = _operators(mesh)
    for name in ("umbrella_matrix", "laplacian_matrix", "normalized_laplacian_matrix", "cotangent_laplacian_matrix"):
        y = applied[name]
        assert np.isfinite(np.asarray(y)).all()
        np.testing.assert_allclose(getattr(S, name)(mesh) @ np.asarray(x), y, rtol=1e-9,
                                   atol=1e-9 * float(jnp.max(jnp.abs(y)) + 1))
    k = S.umbrella_matrix(mesh)
    np.testing.assert_allclose(np.asarray(k.sum(axis=1)).ravel(), 0, atol=1e-12)
    lap = S.laplacian_matrix(mesh)
    assert abs(lap - lap.T).max() == 0

    q, t = motion
    t = t * float(jaxmesh.bounding_box_diagonal(mesh))
    moved = mesh.with_vertices(x @ jnp.asarray(q).T + jnp.asarray(t)[None])
    a, b = _quantities(mesh), _quantities(moved)
    scale = float(jnp.max(jnp.abs(x))) + float(np.max(np.abs(t)))
    for name in SCALARS + VECTORS:
        assert np.isfinite(np.asarray(a[name])).all(), name
    # relative to each quantity's size, loosened by how far the motion moves the mesh
    # (translation costs digits: coordinates of size |t| carry differences of size |x|)
    loose = 1e-9 * (1 + scale / max(float(jnp.max(jnp.abs(x))), 1e-300)) ** 2
    for name in SCALARS:
        ref = float(jnp.max(jnp.abs(a[name])))
        np.testing.assert_allclose(b[name], a[name], rtol=0, atol=loose * (ref + 1e-300), err_msg=name)
    for name in VECTORS:
        want = a[name] @ jnp.asarray(q).T
        ref = float(jnp.max(jnp.abs(want))) if want.size else 0.0
        if name == "normals":   # a direction: skip fans whose face normals (nearly) cancel
            ok = _well_conditioned_normals(mesh)
            want, got = np.asarray(want)[ok], np.asarray(b[name])[ok]
        else:
            got = b[name]
        np.testing.assert_allclose(got, want, rtol=0, atol=loose * (ref + 1e-300), err_msg=name)

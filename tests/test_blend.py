"""Blending two denoisers with a blind weight (jaxmesh.tune.blend)."""

import jax.numpy as jnp
import numpy as np
import pytest
import trimesh

import jaxmesh
from jaxmesh.tune import Candidate, choose_denoiser
from jaxmesh.tune.blend import best_blend, blend_weight, tilt_gram


def _gram(rows):
    t = np.stack([np.ravel(r) for r in rows])
    return t @ t.T


def test_blend_weight_minimises_the_quadratic_by_brute_force():
    rng = np.random.default_rng(0)
    ws = np.linspace(0, 1, 20001)
    for trial in range(5):
        ti, tj = rng.standard_normal((2, 7, 3)) + rng.standard_normal(3) * trial
        w, risk = blend_weight(_gram([ti, tj]), 0, 1)
        grid = [np.sum((tj + v * (ti - tj)) ** 2) for v in ws]
        k = int(np.argmin(grid))
        assert w == pytest.approx(ws[k], abs=1e-4)
        assert risk == pytest.approx(np.sum((tj + w * (ti - tj)) ** 2), rel=1e-12)
        assert risk <= grid[k] + 1e-12


def test_blend_weight_stays_convex_and_handles_equal_rows():
    t = np.arange(6.0)
    assert blend_weight(_gram([t, t]), 0, 1) == (0.0, pytest.approx(t @ t))
    # T_i = 2 T_j: the unconstrained optimum w = -1 is clipped to 0 (f_j alone)
    w, risk = blend_weight(_gram([2 * t, t]), 0, 1)
    assert w == 0.0 and risk == pytest.approx(t @ t)


def test_best_blend_blends_complementary_errors_and_keeps_a_clear_winner():
    rng = np.random.default_rng(1)
    u, v = rng.standard_normal((2, 50))
    v -= (u @ v) / (u @ u) * u                              # u ⟂ v
    rows, risk = best_blend(_gram([u + v, u - v, 3 * u]), winner=0)
    assert [i for i, _ in rows] == [0, 1] and [w for _, w in rows] == pytest.approx([0.5, 0.5])
    assert risk == pytest.approx(u @ u)
    small = 0.01 * u
    rows, risk = best_blend(_gram([u + v, small, u - v]), winner=1)     # the winner is nearly exact
    assert rows == ((1, 1.0),) and risk == pytest.approx(small @ small)


def _noisy_box():
    b = trimesh.creation.box().subdivide().subdivide().subdivide()
    clean = jaxmesh.Mesh.from_arrays(b.vertices, b.faces).astype(jnp.float64)
    return jaxmesh.add_noise(clean, 0.3, 1, along_normals=True)


def test_choose_denoiser_returns_what_its_components_make():
    noisy = _noisy_box()
    cands = [Candidate("taubin", {"iterations": 10}), Candidate("guided_normal", {})]
    single = choose_denoiser(noisy, candidates=cands, paths=(), blend_draws=0)
    assert single.components == ((single.table[0][0], single.table[0][1], 1.0),)
    assert single.method == single.table[0][0]
    c = choose_denoiser(noisy, candidates=cands, paths=(), blend_draws=3)
    assert sum(w for *_, w in c.components) == pytest.approx(1.0)
    want = sum(w * jaxmesh.denoise.denoise(noisy, m, **p).vertices for m, p, w in c.components)
    np.testing.assert_allclose(c.mesh.vertices, want, atol=1e-10)
    assert (c.method == "blend") == (len(c.components) == 2)
    assert [d["weight"] for d in c.summary()["components"]] == [w for *_, w in c.components]
    with pytest.raises(ValueError, match="blend_draws must be an int >= 0"):
        choose_denoiser(noisy, candidates=cands, paths=(), blend_draws=-1)


def test_tilt_gram_matches_a_plain_loop():
    """G against the edge tilts of two Taubin settings summed face by face in numpy."""
    from jaxmesh.geometry import face_normals, mean_edge_length
    from jaxmesh.tune import edge_tilt

    noisy = _noisy_box()
    rows = [("taubin", {"iterations": 3}), ("taubin", {"iterations": 8})]
    nu, ell, a = face_normals(noisy), float(mean_edge_length(noisy)), 0.5
    y, f, nu_np = np.asarray(noisy.vertices), np.asarray(noisy.faces), np.asarray(nu)
    zs = 0.01 * np.random.default_rng(2).standard_normal((2,) + y.shape)

    def out(row, z):
        return np.asarray(jaxmesh.denoise.denoise(noisy.with_vertices(jnp.asarray(y + a * z)), *row[:1],
                                                  **row[1]).vertices) - (y - z / a)

    gram = tilt_gram(rows, zs, lambda row, z: edge_tilt(noisy, nu, ell, jnp.asarray(out(row, z))))
    want = np.zeros((2, 2))
    for z in zs:
        us = [out(row, z) for row in rows]
        for face, normal in zip(f, nu_np):
            for b, c in ((face[1], face[2]), (face[2], face[0]), (face[0], face[1])):
                t = [normal @ (u[b] - u[c]) / ell for u in us]
                want += np.outer(t, t)
    np.testing.assert_allclose(gram, want, rtol=1e-9)

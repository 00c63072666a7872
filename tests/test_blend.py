"""Blending two denoisers with a blind weight (jaxmesh.tune.blend)."""

import itertools

import jax.numpy as jnp
import numpy as np
import pytest
import trimesh

import jaxmesh
from jaxmesh.tune import Candidate, Component, Ranked, choose_denoiser
from jaxmesh.tune.blend import BLEND_MIN_GAIN, best_mixture, mixture_weights, snapshot_rows, tilt_gram, worth_blending


def blend_weight(gram: np.ndarray, i: int, j: int) -> tuple[float, float]:
    """w* and the summed squared tilt ‖T_j + w*(T_i − T_j)‖² of the blend
    w f_i + (1 − w) f_j (module docstring), from the Gram matrix G_kl = ⟨T_k, T_l⟩
    of the denoisers' recorrupted edge tilts (summed over the draws).

    Arguments:
        gram: (K, K) the Gram matrix of the tilts.
        i: the first denoiser's row.
        j: the second's.

    Returns:
        (w*, the blend's summed squared tilt)."""
    g = np.asarray(gram, np.float64)
    dd = g[i, i] - 2 * g[i, j] + g[j, j]                   # ‖T_i − T_j‖²
    de = g[i, j] - g[j, j]                                 # ⟨T_i − T_j, T_j⟩
    w = float(np.clip(-de / dd, 0.0, 1.0)) if dd > 0 else 0.0
    return w, float(g[j, j] + 2 * w * de + w * w * dd)


def best_blend(gram: np.ndarray, winner: int) -> tuple[tuple[tuple[int, float], ...], float]:
    """The best of the single ``winner`` and the convex blend of every pair of denoisers, pair by
    pair in closed form (the reference :func:`best_mixture` with ``size=2`` must agree with).

    Arguments:
        gram: (K, K) the Gram matrix of the K denoisers' recorrupted edge tilts, on the same draws.
        winner: the row of the single winner the blends must beat.

    Returns:
        ((row, weight), ...) of the choice (one row with weight 1.0, or two rows whose
        weights sum to 1), and its summed squared tilt."""
    g = np.asarray(gram, np.float64)
    best: tuple = (((winner, 1.0),), float(g[winner, winner]))
    for i, j in itertools.combinations(range(len(g)), 2):
        w, risk = blend_weight(g, i, j)
        if 0.0 < w < 1.0 and risk < best[1]:
            best = (((i, w), (j, 1.0 - w)), risk)
    return best


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


def _simplex_grid(k: int, steps: int) -> np.ndarray:
    """Every w ≥ 0 with Σw = 1 on a grid of 1/steps (k = 3)."""
    return np.array([(i, j, steps - i - j) for i in range(steps + 1) for j in range(steps + 1 - i)]) / steps


def test_best_mixture_is_the_minimum_over_the_simplex_by_brute_force():
    rng = np.random.default_rng(3)
    grid = _simplex_grid(3, 400)
    for trial in range(6):
        shared = rng.standard_normal(40) * trial
        t = rng.standard_normal((3, 40)) + shared                          # three correlated tilt fields
        g = _gram(t)
        rows, risk = best_mixture(g, winner=int(np.argmin(np.diag(g))), size=3)
        values = np.einsum("nk,kl,nl->n", grid, g, grid)
        assert risk <= values.min() + 1e-9                                  # never worse than the grid
        assert risk == pytest.approx(values.min(), rel=2e-3)                # and the grid gets close to it
        w = np.zeros(3)
        for i, wi in rows:
            w[i] = wi
        assert w.sum() == pytest.approx(1.0) and np.all(w >= 0)
        assert risk == pytest.approx(w @ g @ w, rel=1e-12)
        assert [wi for _, wi in rows] == sorted((wi for _, wi in rows), reverse=True)


def test_best_mixture_of_pairs_is_best_blend_and_more_rows_never_hurt():
    rng = np.random.default_rng(4)
    for trial in range(10):
        g = _gram(rng.standard_normal((5, 30)) + rng.standard_normal(30))
        winner = int(np.argmin(np.diag(g)))
        pairs, pair_risk = best_blend(g, winner)
        rows, risk = best_mixture(g, winner, size=2)
        assert dict(rows) == pytest.approx(dict(pairs)) and risk == pytest.approx(pair_risk, rel=1e-12)
        assert best_mixture(g, winner, size=4)[1] <= pair_risk + 1e-9
        assert best_mixture(g, winner, size=1) == (((winner, 1.0),), float(g[winner, winner]))


def test_a_blend_must_gain_a_share_of_the_winners_estimated_risk():
    """By hand: the winner sums 110 over 10 faces × draws with the noise constant 1, so its
    estimated risk is 11 − 1 = 10; a blend is taken when it gains at least 1% of that (0.1 a
    face-draw: a total of at most 109), and never when it sums no less than the winner."""
    gram = np.array([[110.0, 0.0], [0.0, 130.0]])
    assert BLEND_MIN_GAIN == 0.01
    assert worth_blending(gram, 0, 108.95, 1.0, 10)
    assert not worth_blending(gram, 0, 109.05, 1.0, 10)
    assert not worth_blending(gram, 0, 110.0, 1.0, 10, min_gain=0.0)
    assert worth_blending(gram, 0, 109.9, 1.0, 10, min_gain=0.0)
    # the held-out estimate has no constant: 1% of 11 is 0.11 a face-draw
    assert worth_blending(gram, 0, 108.85, 0.0, 10) and not worth_blending(gram, 0, 108.95, 0.0, 10)
    # a winner estimated at or below zero risk: any lower blend is taken
    assert worth_blending(gram, 0, 109.99, 12.0, 10)


def test_mixture_weights_refuse_singular_and_boundary_sets():
    u, v = np.eye(6)[0] * 3, np.eye(6)[1]                                   # u ⟂ v
    g = _gram([u + v, u + v, -u + v])
    assert mixture_weights(g, (0, 1)) is None                               # equal rows: singular
    w, risk = mixture_weights(g, (0, 2))                                    # half each cancels u
    assert w == pytest.approx([0.5, 0.5]) and risk == pytest.approx(v @ v)
    assert mixture_weights(_gram([2 * u, u]), (0, 1)) is None               # the optimum w = (−1, 2) is outside
    rows, risk = best_mixture(g, winner=0, size=3)                          # the singular sets are skipped
    assert risk == pytest.approx(v @ v) and len(rows) == 2 and rows[0][1] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="size must be a positive int"):
        best_mixture(g, 0, size=0)


def test_snapshots_scale_the_path_leaders_counts_once_each():
    leaders = [("guided_normal", {"sigma_r": 0.3}, 1.0), ("taubin", {"lam": 0.5, "iterations": 9}, 0.5),
               ("bilateral_normal", {"sigma_s": 1.0, "iterations": 1}, 0.7)]
    out = snapshot_rows(leaders[1:], (0.5, 2.0, 2.1), leaders)
    assert [(m, p["iterations"]) for m, p, _ in out] == [("taubin", 4), ("taubin", 18), ("taubin", 19),
                                                          ("bilateral_normal", 2)]
    assert all(p["lam"] == 0.5 for m, p, _ in out if m == "taubin") and all(r is None for *_, r in out)
    assert snapshot_rows(leaders[1:], (), leaders) == []


def _noisy_box():
    b = trimesh.creation.box().subdivide().subdivide().subdivide()
    clean = jaxmesh.Mesh.from_arrays(b.vertices, b.faces).astype(jnp.float64)
    return jaxmesh.add_noise(clean, 0.3, 1, along_normals=True)


def test_choose_denoiser_returns_what_its_components_make():
    noisy = _noisy_box()
    cands = [Candidate("taubin", {"iterations": 10}), Candidate("guided_normal", {})]
    single = choose_denoiser(noisy, candidates=cands, paths=(), blend_draws=0)
    best = single.table[0]
    assert single.components == (Component(best.method, best.params, 1.0),) and single.method == best.method
    assert all(isinstance(r, Ranked) for r in single.table)
    assert [r.risk for r in single.table] == sorted(r.risk for r in single.table)
    assert single.summary()["candidates"][0] == {"method": best.method, "params": best.params, "risk": best.risk}
    c = choose_denoiser(noisy, candidates=cands, paths=(), blend_draws=3)
    assert sum(w for *_, w in c.components) == pytest.approx(1.0)
    want = sum(w * jaxmesh.denoise.denoise(noisy, m, **p).vertices for m, p, w in c.components)
    np.testing.assert_allclose(c.mesh.vertices, want, atol=1e-10)
    assert (c.method == "blend") == (len(c.components) >= 2)
    assert [d["weight"] for d in c.summary()["components"]] == [w for *_, w in c.components]
    with pytest.raises(ValueError, match="blend_draws must be an int >= 0"):
        choose_denoiser(noisy, candidates=cands, paths=(), blend_draws=-1)
    with pytest.raises(ValueError, match="blend_size must be an int >= 1"):
        choose_denoiser(noisy, candidates=cands, paths=(), blend_size=0)
    for bad in ((0.5, -1.0), (float("nan"),), (0.0,)):
        with pytest.raises(ValueError, match="snapshots must be a sequence of positive numbers"):
            choose_denoiser(noisy, candidates=cands, paths=(), snapshots=bad)


def test_choose_denoiser_blends_snapshots_of_a_path():
    """A Taubin path and one fixed candidate: up to three rows (its leader, two snapshots and the
    candidate) mix, and the output is what the components make."""
    noisy = _noisy_box()
    path = jaxmesh.tune.SearchPath("taubin", ({"lam": 0.5, "mu": -0.53},), (), 12)
    c = choose_denoiser(noisy, candidates=[Candidate("guided_normal", {})], paths=(path,), blend_draws=3,
                        blend_size=3, snapshots=(0.5, 2.0))
    assert 1 <= len(c.components) <= 3 and sum(w for *_, w in c.components) == pytest.approx(1.0)
    want = sum(w * jaxmesh.denoise.denoise(noisy, m, **p).vertices for m, p, w in c.components)
    np.testing.assert_allclose(c.mesh.vertices, want, atol=1e-10)
    pairs = choose_denoiser(noisy, candidates=[Candidate("guided_normal", {})], paths=(path,), blend_draws=3,
                            blend_size=2, snapshots=())
    if len(c.components) > 1 and len(pairs.components) > 1:     # both blend: more rows, no larger estimate
        assert c.risk <= pairs.risk + 1e-12


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

    tilts = np.stack([[np.asarray(edge_tilt(noisy, nu, ell, jnp.asarray(out(row, z)))) for z in zs] for row in rows])
    gram = tilt_gram(tilts)
    want = np.zeros((2, 2))
    for z in zs:
        us = [out(row, z) for row in rows]
        for face, normal in zip(f, nu_np):
            for b, c in ((face[1], face[2]), (face[2], face[0]), (face[0], face[1])):
                t = [normal @ (u[b] - u[c]) / ell for u in us]
                want += np.outer(t, t)
    np.testing.assert_allclose(gram, want, rtol=1e-9)


def test_a_row_runs_as_the_race_ran_it():
    """A setting of a search path at any count runs with its count traced (and the rim held on patches); a
    fixed candidate of the same method runs whole, as the race ran it, even where its parameters name an
    iteration count."""
    from jaxmesh.tune.auto import PATHS, _on_path
    from jaxmesh.tune.paths import BILATERAL_PATH_FIXED, BILATERAL_PATH_SIGMAS, TAUBIN_LAMS, taubin_mu

    ss, sr = BILATERAL_PATH_SIGMAS[0]
    on = [Candidate("bilateral_normal", {"sigma_s": ss, "sigma_r": sr, **BILATERAL_PATH_FIXED, "iterations": 7}),
          Candidate("taubin", {"lam": TAUBIN_LAMS[0], "mu": taubin_mu(TAUBIN_LAMS[0], 0.0), "iterations": 40})]
    off = [Candidate("bilateral_normal", {"sigma_r": 0.35, "sigma_s": 2.0}),
           Candidate("bilateral_normal", {"sigma_s": ss, "sigma_r": sr, "iterations": 7}),   # not the path's statics
           Candidate("taubin", {"lam": TAUBIN_LAMS[0], "mu": -0.9, "iterations": 40}),
           Candidate("guided_normal", {"sigma_s": ss, "sigma_r": sr, **BILATERAL_PATH_FIXED})]
    assert [_on_path(c, PATHS) for c in on] == [True, True]
    assert [_on_path(c, PATHS) for c in off] == [False] * 4
    assert not _on_path(on[0], ())

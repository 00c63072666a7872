"""The held-out estimate of the blind chooser under impulsive noise (jaxmesh.tune.heldout)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest
import trimesh

import jaxmesh
import jaxmesh.tune.heldout
from jaxmesh.denoise import METHODS
from jaxmesh.geometry import face_normals, mean_edge_length, vertex_normals
from jaxmesh.metrics import mean_normal_angle_error
from jaxmesh.tune import Candidate, choose_denoiser
from jaxmesh.tune.heldout import (DISPLACED_FACTOR, HELD_OUT_TOLERANCE, STRATUM_MIN_FACES, feature_faces,
                                  held_out_inputs, held_out_split, measured_faces, stratum_weights)


@pytest.fixture(scope="module")
def ball():
    s = trimesh.creation.icosphere(4)                       # 2562 vertices
    return jaxmesh.Mesh.from_arrays(s.vertices, s.faces).astype(jnp.float64)


def test_the_split_reads_residuals_against_the_nearest_fit(ball):
    """Against the clean mesh as the fit, an untouched vertex has residual 0 (untouched) and one moved
    along its normal by more than 3τℓ̄ is displaced; a second, farther fit changes nothing (the least
    residual counts).  Reference: numpy residuals along the clean normals."""
    ell = float(mean_edge_length(ball))
    noisy = jaxmesh.add_impulsive_noise(ball, 0.5, 1, fraction=0.4)
    n = np.asarray(vertex_normals(ball, "area"))
    r = np.abs(np.sum((np.asarray(noisy.vertices) - np.asarray(ball.vertices)) * n, axis=1)) / ell
    untouched, displaced = held_out_split(noisy, (ball,), ell)
    np.testing.assert_array_equal(untouched, r < HELD_OUT_TOLERANCE)
    np.testing.assert_array_equal(displaced, r > DISPLACED_FACTOR * HELD_OUT_TOLERANCE)
    assert untouched[r == 0].all() and 0.3 < displaced.mean() < 0.45
    far = ball.with_vertices(ball.vertices * 1.2)
    both = held_out_split(noisy, (far, ball), ell)
    np.testing.assert_array_equal(both[0], untouched)
    np.testing.assert_array_equal(both[1], displaced)
    with pytest.raises(ValueError, match="at least one"):
        held_out_split(noisy, (), ell)


def test_measured_faces_have_three_untouched_vertices():
    faces = np.array([[0, 1, 2], [1, 2, 3], [2, 3, 4]])
    mesh = jaxmesh.Mesh.from_arrays(np.random.default_rng(0).random((5, 3)), faces)
    np.testing.assert_array_equal(measured_faces(mesh, np.array([1, 1, 1, 0, 1], bool)), [True, False, False])


def test_feature_faces_are_the_faces_touching_a_crease():
    """On a subdivided cube, exactly the faces with a vertex on a cube edge (hand-derived: a vertex with
    two of its coordinates at ±0.5)."""
    b = trimesh.creation.box().subdivide().subdivide()
    box = jaxmesh.Mesh.from_arrays(b.vertices, b.faces).astype(jnp.float64)
    on_edge = np.sum(np.isclose(np.abs(np.asarray(box.vertices)), 0.5), axis=1) >= 2
    want = on_edge[np.asarray(box.faces)].any(axis=1)
    np.testing.assert_array_equal(feature_faces(box, face_normals(box)), want)
    assert 0 < want.mean() < 1


def test_stratum_weights_restore_each_strata_share():
    """Each stratum's weights sum to its share of the counted faces times |M| (the weights sum to |M|);
    a stratum with too few measured faces leaves the weights at 1."""
    rng = np.random.default_rng(0)
    feature = np.arange(2000) < 600                          # 30% of the faces
    measured = np.where(feature, rng.random(2000) < 0.2, rng.random(2000) < 0.6)
    counted = np.ones(2000, bool)
    w = stratum_weights(feature, measured, counted)
    m = measured.sum()
    assert w[~measured].sum() == 0 and w.sum() == pytest.approx(m)
    assert w[feature].sum() == pytest.approx(0.3 * m) and w[~feature].sum() == pytest.approx(0.7 * m)
    few = measured & ~(feature & (np.cumsum(feature & measured) > STRATUM_MIN_FACES - 1))
    np.testing.assert_array_equal(stratum_weights(feature, few, counted), few.astype(float))


def test_each_draw_displaces_the_untouched_at_the_law_and_puts_displaced_back(ball):
    """Untouched vertices move along n with probability p̂ by N(0, σ̂²); displaced ones are put back at
    the repair's position with probability min(1, p̂|U|/|D|); the others stay.  Same key, same draws;
    a salt draws others."""
    rng = np.random.default_rng(3)
    v = ball.num_vertices
    untouched = rng.random(v) < 0.6
    displaced = ~untouched & (rng.random(v) < 0.8)
    repaired = np.asarray(ball.vertices) + 1.0
    n = np.asarray(vertex_normals(ball, "area"))
    x = np.asarray(held_out_inputs(ball, untouched, displaced, repaired, n, 0.05, 0.5, 400, 7))
    d = x - np.asarray(ball.vertices)[None]
    along = np.sum(d * n[None], axis=-1)
    hit = untouched[None] & (np.abs(along) > 0)
    np.testing.assert_allclose(d[hit], along[hit][:, None] * np.broadcast_to(n, d.shape)[hit], atol=1e-12)
    assert hit[:, untouched].mean() == pytest.approx(0.5, abs=0.01)
    assert np.std(along[hit]) == pytest.approx(0.05, rel=0.02)
    back = np.all(np.isclose(x, repaired[None]), axis=-1)
    rate = min(1.0, 0.5 * untouched.sum() / displaced.sum())
    assert back[:, displaced].mean() == pytest.approx(rate, abs=0.01) and not back[:, ~displaced].any()
    assert np.all(d[:, ~untouched & ~displaced] == 0)
    again = held_out_inputs(ball, untouched, displaced, repaired, n, 0.05, 0.5, 400, 7)
    np.testing.assert_array_equal(again, x)
    other = held_out_inputs(ball, untouched, displaced, repaired, n, 0.05, 0.5, 400, 7, salt=1)
    assert not np.array_equal(np.asarray(other), x)


def _numpy_tilt_risk(mesh, nu, ell, outputs, y):
    """Σ_d Σ_f Σ_edges (ν_f · (u_b − u_c) / ℓ̄)² / (D F), u = output − y, a plain loop over the edges."""
    f = np.asarray(mesh.faces)
    total = 0.0
    for out in outputs:
        u = np.asarray(out) - np.asarray(y)
        for b, c in ((1, 2), (2, 0), (0, 1)):
            total += np.sum((np.sum(nu * (u[f[:, b]] - u[f[:, c]]), axis=1) / ell) ** 2)
    return total / len(outputs) / mesh.num_faces


def test_the_chooser_ranks_impulsive_noise_by_the_held_out_estimate(ball):
    """The table's estimate of a candidate is the weighted edge-tilt risk of its outputs on the held-out
    draws against the noisy mesh, over the measured faces, recomputed here with numpy from the
    module's pieces (same key)."""
    noisy = jaxmesh.add_impulsive_noise(ball, 0.5, 3, fraction=0.5)
    taubin = Candidate("taubin", {"iterations": 5})
    c = choose_denoiser(noisy, candidates=[taubin], impulsive_candidates=(), paths=(), blend_draws=0, draws=2,
                        race_keep=None, key=4)
    assert c.noise_law == "impulsive" and c.estimator == "held_out" and c.summary()["estimator"] == "held_out"
    ell = float(mean_edge_length(noisy))
    pilot = METHODS["guided_normal"](noisy)
    repaired = METHODS["impulse_repair"](noisy)
    untouched, displaced = held_out_split(noisy, (repaired, pilot), ell)
    measured = measured_faces(noisy, untouched)
    w = stratum_weights(feature_faces(noisy, face_normals(pilot)), measured, np.ones(noisy.num_faces, bool))
    nu = np.asarray(face_normals(noisy)) * np.sqrt(w)[:, None]
    inputs = held_out_inputs(noisy, untouched, displaced, repaired.vertices, vertex_normals(pilot, "area"),
                             c.sigma, c.fraction, 2, 4)
    outputs = [METHODS["taubin"](noisy.with_vertices(x), iterations=5).vertices for x in inputs]
    per_face = noisy.num_faces / measured.sum()
    assert c.table[0][2] == pytest.approx(_numpy_tilt_risk(noisy, nu, ell, outputs, noisy.vertices) * per_face,
                                          rel=1e-6)
    assert c.noisy_risk == pytest.approx(_numpy_tilt_risk(noisy, nu, ell, inputs, noisy.vertices) * per_face,
                                         rel=1e-6)


@pytest.mark.slow   # a statistical check of the estimate's order (the chooser's use of it: the test above)
def test_the_held_out_estimate_orders_impulse_repair_as_the_clean_mesh_does(ball):
    """Impulse repair at α = 0.1 and α = 10 on the ball at p = 0.5: the chooser picks the one with the
    lower true normal error."""
    noisy = jaxmesh.add_impulsive_noise(ball, 0.5, 5, fraction=0.5)
    settings = [Candidate("impulse_repair", {"alpha": a}) for a in (0.1, 10.0)]
    c = choose_denoiser(noisy, candidates=settings, impulsive_candidates=(), paths=(), blend_draws=0)
    true = [float(mean_normal_angle_error(ball, METHODS["impulse_repair"](noisy, **s.params))) for s in settings]
    assert c.params == settings[int(np.argmin(true))].params and min(true) < 0.8 * max(true)


def test_too_few_untouched_faces_fall_back_to_the_recorrupted_estimate(ball, monkeypatch):
    """Where fewer than HELD_OUT_MIN_FACES faces can be scored (here: the threshold raised past the
    mesh's faces), the per-vertex recorruption ranks, with its noise constant.  Ranked by the held-out
    estimate the race's winner is the choice, alone (the blend stage does not run: its Gram matrix is
    never formed); ranked by the recorruption, the leaders' blend is judged."""
    import jaxmesh.tune.auto as auto

    grams, real = [], auto.tilt_gram
    monkeypatch.setattr(auto, "tilt_gram", lambda tilts: grams.append(len(tilts)) or real(tilts))
    noisy = jaxmesh.add_impulsive_noise(ball, 0.5, 3, fraction=0.5)
    kw = dict(candidates=[Candidate("taubin", {"iterations": 5}), Candidate("impulse_repair", {"iterations": 1})],
              impulsive_candidates=(), paths=(), blend_draws=2)
    held = choose_denoiser(noisy, **kw)
    assert held.estimator == "held_out" and len(held.components) == 1 and grams == []
    assert held.components[0].weight == 1.0 and (held.method, held.params) == held.table[0][:2]
    monkeypatch.setattr(jaxmesh.tune.heldout, "HELD_OUT_MIN_FACES", ball.num_faces + 1)
    c = choose_denoiser(noisy, **kw)
    assert c.noise_law == "impulsive" and c.estimator == "recorrupted" and grams == [2]
    assert c.table[0][2] != held.table[0][2]

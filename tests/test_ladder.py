"""The blind search's mesh padded to a size ladder (jaxmesh.tune.ladder): the padded tables give the
unpadded filters on the real vertices, meshes of one rung get tables of one shape, and the padded
search makes the unpadded one's choice with the same estimates."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import trimesh

import jaxmesh
from jaxmesh.geometry import face_normals, mean_edge_length, vertex_normals
from jaxmesh.hashing.attacks import simplify
from jaxmesh.host import HostMesh
from jaxmesh.tune import Candidate, SearchPath, choose_denoiser
from jaxmesh.tune.ladder import SEARCH_LADDER, _tiers, ladder_shape, pad_search, table_width
from jaxmesh.tune.race import run_setting
from jaxmesh.tune.recorrupt import recorruptions


@pytest.fixture(scope="module")
def noisy():
    s = trimesh.creation.icosphere(3)                                  # 642 vertices
    s.vertices[::7] *= 1.05                                            # an uneven surface, valences 5 and 6
    mesh = jaxmesh.Mesh.from_arrays(s.vertices, s.faces)
    return jaxmesh.add_noise(simplify(mesh, 0.9), 0.3, 0)             # valences up to 8 or 9


def test_tiers_by_hand():
    """27 rows of widths 13 (20 rows), 15 (5) and 20 (2) into tiers 13/16/24 in steps of ⌈27/8⌉ = 4 rows:
    the widest tier takes the 2 rows over 16 and the next two widest, the middle tier 4 rows (the 3
    remaining rows over 13 and one more), the narrow tier the other 19."""
    counts = np.array([13] * 10 + [15] * 5 + [13] * 10 + [20] * 2)
    groups, widths = _tiers(counts, (13, 16), 24)
    assert widths == [13, 16, 24] and [g.size for g in groups] == [19, 4, 4]
    assert sorted(np.concatenate(groups).tolist()) == list(range(27))
    for g, w in zip(groups, widths):
        assert (counts[g] <= w).all()
    assert {25, 26} <= set(groups[2].tolist())
    one, w = _tiers(np.full(10, 12), (13, 16), 24)
    assert w == [24] and one[0].tolist() == list(range(10))
    assert [table_width(k) for k in (1, 8, 9, 17, 64, 65)] == [12, 12, 12, 24, 64, 96]


@pytest.mark.parametrize("method, params, counted", [
    ("guided_normal", {}, False),
    ("guided_normal", {"sigma_r": 0.3, "sigma_s": 2.0}, False),
    ("bilateral_normal", {"sigma_r": 0.35, "sigma_s": 1.0}, False),
    ("taubin", {"lam": 0.5, "mu": -0.53, "iterations": 7}, True),
    ("bilateral_normal", {"sigma_r": 1.0, "sigma_s": 1.5, "normal_iterations": 1, "vertex_iterations": 5,
                          "iterations": 3}, True),
])
def test_the_padded_tables_give_the_unpadded_filters(noisy, method, params, counted):
    """Each searched family on the padded mesh with its padded tables: the real vertices as on the
    mesh itself, the padding vertices left at the origin, nothing non-finite."""
    host = HostMesh(noisy)
    padded, core, rim = pad_search(host, None, None)
    shape = ladder_shape(noisy)
    assert (padded.mesh.num_vertices, padded.mesh.num_faces, padded.mesh.num_edges) == shape
    assert core.sum() == noisy.num_faces and core[:noisy.num_faces].all() and rim is None
    plain = np.asarray(run_setting(noisy, noisy.vertices, method, params, host.aux(method), counted))
    out = np.asarray(run_setting(padded.mesh, padded.mesh.vertices, method, params, padded.aux(method), counted))
    assert np.isfinite(out).all()
    np.testing.assert_allclose(out[:noisy.num_vertices], plain, rtol=0, atol=1e-5)
    assert not out[noisy.num_vertices:].any()


def test_meshes_of_one_rung_get_tables_of_one_shape(noisy):
    """A mesh and its simplification whose sizes round to the same rung and whose widest rows to the same
    widths: every array the search's programs take (the mesh, the face graph, the one-rings) has one
    shape for both; the tiers hold every face once, each within its tier's width."""
    other = simplify(noisy, 0.97)
    assert other.num_vertices < noisy.num_vertices and ladder_shape(other) == ladder_shape(noisy)
    shapes = []
    for mesh in (noisy, other):
        padded = pad_search(HostMesh(mesh), None, None)[0]
        graph = padded.aux("guided_normal")["graph"]
        shapes.append([x.shape for x in jax.tree.leaves((padded.mesh, graph, padded.aux("taubin")))])
        counts = np.asarray(graph.ring_mask).sum(axis=1)
        faces = np.concatenate([np.asarray(t.faces) for t in graph.tiers])
        assert sorted(faces.tolist()) == list(range(padded.mesh.num_faces))
        for t in graph.tiers:
            assert (counts[np.asarray(t.faces)] <= t.ring.shape[1]).all()
        np.testing.assert_array_equal(faces[np.asarray(graph.tier_order)], np.arange(padded.mesh.num_faces))
    assert shapes[0] == shapes[1]


def test_recorruptions_on_the_real_vertices_are_the_unpadded_draws(noisy):
    """With ``vertices``, the fields on the padded mesh are the unpadded mesh's on its vertices, zero on the
    padding ones; the trace per face scales by F / F_p (the padding faces have ν = 0)."""
    padded, core, _ = pad_search(HostMesh(noisy), None, None)
    ell, v, f = float(mean_edge_length(noisy)), noisy.num_vertices, noisy.num_faces
    nu, n = face_normals(noisy), vertex_normals(noisy)
    nu_p = jnp.concatenate([nu, jnp.zeros((padded.mesh.num_faces - f, 3), nu.dtype)])
    n_p = jnp.concatenate([n, jnp.zeros((padded.mesh.num_vertices - v, 3), n.dtype)])
    z, trace = recorruptions(noisy, nu, n, ell, 0.01, 0.004, 3, 5)
    zp, trace_p = recorruptions(padded.mesh, nu_p, n_p, ell, 0.01, 0.004, 3, 5, vertices=v)
    np.testing.assert_array_equal(np.asarray(zp)[:, :v], np.asarray(z))
    assert not np.asarray(zp)[:, v:].any()
    assert trace_p * padded.mesh.num_faces == pytest.approx(trace * f, rel=1e-5)


def test_the_padded_search_makes_the_unpadded_choice(noisy):
    """choose_denoiser on the padded mesh and unpadded (the default): the same table of settings, estimates
    equal to rounding, the same choice and output; the result reports the real vertex count."""
    kw = dict(candidates=[Candidate("guided_normal", {"sigma_r": r}) for r in (0.2, 0.45)],
              paths=(SearchPath("taubin", ({"lam": 0.5, "mu": -0.53}, {"lam": 0.3, "mu": -0.31}), (), 12),),
              noise_model="normal")
    padded, plain = choose_denoiser(noisy, ladder=SEARCH_LADDER, **kw), choose_denoiser(noisy, **kw)
    assert [r[:2] for r in padded.table] == [r[:2] for r in plain.table]
    np.testing.assert_allclose([r[2] for r in padded.table], [r[2] for r in plain.table], rtol=1e-4)
    assert (padded.method, padded.params) == (plain.method, plain.params)
    assert padded.risk == pytest.approx(plain.risk, rel=1e-4)
    assert padded.noisy_risk == pytest.approx(plain.noisy_risk, rel=1e-4)
    assert padded.search_vertices == plain.search_vertices == noisy.num_vertices
    np.testing.assert_allclose(np.asarray(padded.mesh.vertices), np.asarray(plain.mesh.vertices), atol=1e-5)


@pytest.mark.parametrize("ladder", [1.0, 0.5, True, float("inf")])
def test_a_bad_ladder_is_refused(noisy, ladder):
    with pytest.raises(ValueError, match="ladder must be None or a finite number > 1"):
        choose_denoiser(noisy, ladder=ladder)

"""The blind search's size ladder (jaxmesh.tune.ladder, jaxmesh.denoise.pad_face_graph):
the padding changes no result, and meshes of similar sizes get one shape, hence one
compiled program."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import trimesh

import jaxmesh
from conftest import grid_arrays
from jaxmesh.denoise import face_graph
from jaxmesh.host import HostMesh
from jaxmesh.noise import add_noise
from jaxmesh.tune.ladder import RING_WIDTH, SEARCH_LADDER, TIER_WIDTHS, pad_search, padded_width
from jaxmesh.tune.race import run_setting
from jaxmesh.tune.recorrupt import recorruptions


def _noisy(vertices, faces, seed=0) -> jaxmesh.Mesh:
    mesh = jaxmesh.Mesh.from_arrays(vertices, faces).astype(jnp.float64)
    return add_noise(mesh, 0.3 * float(jaxmesh.geometry.mean_edge_length(mesh)), seed)


@pytest.fixture(scope="module")
def meshes():
    ball = trimesh.creation.icosphere(3)
    # a closed surface, and an open one whose boundary edges have one face (masked in the face graph)
    return [_noisy(ball.vertices, ball.faces), _noisy(*grid_arrays(20, 14, jitter=0.05), seed=1)]


def test_padded_widths_by_hand():
    assert [padded_width(n) for n in (1, 2, 3, 4, 5, 7, 8, 9, 12, 13, 17, 24, 25, 33, 49)] == \
           [2, 2, 3, 4, 6, 8, 8, 12, 12, 16, 24, 24, 32, 48, 64]


def test_the_padded_graph_holds_each_real_ring_and_nothing_else(meshes):
    """Gathered through ``tier_order``, each real face's tier ring holds exactly its ring in the
    graph of the real mesh; each padded face's, itself alone; the patch edges and edge arrays keep
    the real entries and mask the rest; the tiers cut the faces by ring size at the fixed fractions."""
    for mesh in meshes:
        search = pad_search(HostMesh(mesh))
        real, padded = face_graph(mesh), search.aux("guided_normal")["graph"]
        nf, faces = mesh.num_faces, search.mesh.num_faces
        assert padded.ring.shape == (faces, max(padded_width(real.ring.shape[1]), RING_WIDTH))
        assert [t.ring.shape[1] for t in padded.tiers][:1] == [TIER_WIDTHS[0]]
        members = np.concatenate([np.asarray(t.faces) for t in padded.tiers])
        width = padded.ring.shape[1]
        rings = np.concatenate([np.pad(np.where(np.asarray(t.ring_mask), np.asarray(t.ring), -1),
                                       ((0, 0), (0, width - t.ring.shape[1])), constant_values=-1)
                                for t in padded.tiers])
        order = np.asarray(padded.tier_order)
        np.testing.assert_array_equal(members[order], np.arange(faces))
        ring_sets = [set(r[r >= 0]) for r in rings[order]]
        want = [set(np.asarray(real.ring)[f][np.asarray(real.ring_mask)[f]]) for f in range(nf)]
        assert ring_sets[:nf] == want
        assert ring_sets[nf:] == [{f} for f in range(nf, faces)]
        sizes = np.asarray(padded.ring_mask).sum(axis=1)[members]
        assert np.all(np.diff(sizes) >= 0)                                  # smallest rings first
        for name in ("patch_edges", "edge_faces", "edge_apex"):
            r, p = np.asarray(getattr(real, name)), np.asarray(getattr(padded, name))
            np.testing.assert_array_equal(p[:r.shape[0], :r.shape[1]], r)
        np.testing.assert_array_equal(np.asarray(padded.patch_edge_mask)[:nf, :real.patch_edges.shape[1]],
                                      np.asarray(real.patch_edge_mask))
        assert not np.asarray(padded.patch_edge_mask)[nf:].any()
        assert not np.asarray(padded.patch_edge_mask)[:, real.patch_edges.shape[1]:].any()
        np.testing.assert_array_equal(np.asarray(padded.edge_mask)[:mesh.num_edges], np.asarray(real.edge_mask))
        assert not np.asarray(padded.edge_mask)[mesh.num_edges:].any()


@pytest.mark.parametrize("method, params, counted", [
    ("guided_normal", {"sigma_r": 0.3, "sigma_s": 2.0}, False),
    ("bilateral_normal", {"sigma_r": 0.35, "sigma_s": 1.0}, False),
    ("bilateral_normal", {"sigma_r": 1.0, "sigma_s": 1.5, "normal_iterations": 1, "vertex_iterations": 5,
                          "iterations": 3}, True),
    ("taubin", {"lam": 0.5, "mu": -0.53, "iterations": 4}, True),
])
def test_the_search_methods_ignore_the_padding(meshes, method, params, counted):
    """Each method the search runs gives, on the padded mesh with its padded aux, the real mesh's
    result on the real vertices (to the order of sums) and leaves the padded vertices at 0."""
    for mesh in meshes:
        search = pad_search(HostMesh(mesh))
        want = np.asarray(run_setting(mesh, mesh.vertices, method, params, HostMesh(mesh).aux(method), counted))
        got = np.asarray(run_setting(search.mesh, search.mesh.vertices, method, params, search.aux(method), counted))
        np.testing.assert_allclose(got[:mesh.num_vertices], want, rtol=0, atol=1e-12)
        assert not np.any(got[mesh.num_vertices:])


def test_meshes_on_one_rung_share_every_shape():
    """Two different meshes (other vertex, face and edge counts, other rings) whose sizes fall on
    one rung give search meshes and face graphs of identical structure and shapes: what JAX keys
    its compiled programs by.  Sizes across rungs differ."""
    a = trimesh.creation.icosphere(3)                       # 642 vertices, closed
    b = trimesh.Trimesh(a.vertices, a.faces[40:])           # an open one: fewer vertices, faces and edges
    b.remove_unreferenced_vertices()
    c = trimesh.creation.icosphere(4)
    assert len(b.vertices) < len(a.vertices)
    specs = []
    for s in (a, b, c):
        search = pad_search(HostMesh(_noisy(s.vertices, s.faces)))
        tree = (search.mesh, search.aux("guided_normal"))
        specs.append((jax.tree.structure(tree), [x.shape for x in jax.tree.leaves(tree)]))
    assert specs[0] == specs[1]
    assert specs[0][1] != specs[2][1]


def test_recorruptions_draw_the_real_vertices_as_unpadded(meshes):
    """``size=``: the real vertices draw what they draw on the unpadded mesh, the padded ones 0,
    and the trace is the same sum over faces (the padded faces' normals zeroed)."""
    mesh = meshes[0]
    search = pad_search(HostMesh(mesh))
    nv, nf = mesh.num_vertices, mesh.num_faces
    n = jaxmesh.geometry.vertex_normals(mesh, "area")
    nu = jaxmesh.geometry.face_normals(mesh)
    s = np.linspace(0.01, 0.02, nv)
    z, trace = recorruptions(mesh, nu, n, 0.1, s, 0.004, 3, 7)
    n_pad = jnp.concatenate([n, jnp.zeros((search.mesh.num_vertices - nv, 3))])
    nu_pad = jnp.concatenate([nu, jnp.zeros((search.mesh.num_faces - nf, 3))])
    z_pad, trace_pad = recorruptions(search.mesh, nu_pad, n_pad, 0.1, s, 0.004, 3, 7, size=nv)
    np.testing.assert_array_equal(np.asarray(z_pad)[:, :nv], np.asarray(z))
    assert not np.any(np.asarray(z_pad)[:, nv:])
    np.testing.assert_allclose(trace_pad * search.mesh.num_faces, trace * nf, rtol=1e-13)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::jaxmesh.tune.BlindTuningWarning")     # the blind caveats: beside the point here
def test_the_blind_choice_is_the_unpadded_one(meshes):
    """choose_denoiser(search_ladder=...) ranks on the padded mesh: the same components as ranking
    on the mesh itself, weights and risks within 1e-9, the output within 1e-12."""
    from jaxmesh.tune import choose_denoiser

    for mesh in meshes:
        padded, plain = choose_denoiser(mesh, search_ladder=SEARCH_LADDER), choose_denoiser(mesh)
        assert [(c.method, c.params) for c in padded.components] == [(c.method, c.params) for c in plain.components]
        np.testing.assert_allclose([c.weight for c in padded.components], [c.weight for c in plain.components],
                                   rtol=0, atol=1e-9)
        np.testing.assert_allclose(padded.risk, plain.risk, rtol=1e-9)
        np.testing.assert_allclose(np.asarray(padded.mesh.vertices), np.asarray(plain.mesh.vertices), rtol=0,
                                   atol=1e-12)


def test_search_ladder_is_refused_unless_a_ratio_above_one(meshes):
    from jaxmesh.tune import choose_denoiser

    for bad in (1.0, 0.5, float("inf"), float("nan"), True):
        with pytest.raises(ValueError, match="search_ladder must be None or a finite number > 1"):
            choose_denoiser(meshes[0], search_ladder=bad)


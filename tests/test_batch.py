"""Padded batches of different meshes and sharding over (fake CPU) devices."""

import os
import subprocess
import sys
import textwrap

import jax
import numpy as np
import pytest
import trimesh

import jaxmesh
from jaxmesh.batch import pack_batch, packed_spec, pad_batch, shard, unpack, unpad
from jaxmesh.denoise import METHODS, Method, denoise_in_unit_frame, denoise_packed, diverged, packed_run
from jaxmesh.metrics import visual_error

from conftest import assert_refused, grid_arrays, octahedron_arrays


@pytest.fixture(scope="module")
def three_meshes():
    """Three noisy meshes of different sizes, the largest a sphere (642 vertices): the padding
    logic does not need the 2.9k-vertex spot, whose solves made the per-method calls here
    compute-bound."""
    s = trimesh.creation.icosphere(3)
    ball = jaxmesh.Mesh.from_arrays(s.vertices, s.faces)
    grid = jaxmesh.Mesh.from_arrays(*grid_arrays(6, 5, jitter=0.1, seed=2))
    octa = jaxmesh.Mesh.from_arrays(*octahedron_arrays())
    return [jaxmesh.add_noise(m, 0.2, k) for k, m in enumerate([grid, ball, octa])]


# methods with a host-built face graph (the median and the feature-preserving filters) batch
# over copies of one mesh (tests/test_denoise_methods.py), not over padded different meshes:
# the graph of each mesh would have to be padded too (noted for the dataset-runner issue)
# impulse_repair (9 s) and the two slowest to compile (~3 s each) run with -m slow
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow)
                                  if n in ("impulse_repair", "cauchy_diffusion", "geometric") else n
                                  for n in sorted(METHODS) if not METHODS[n].aux])
def test_padded_batch_equals_single_calls(three_meshes, name):
    batch = pad_batch(three_meshes)
    out = jax.vmap(lambda m: METHODS[name](m))(batch.mesh)
    x = np.asarray(out.vertices)
    assert np.all(x[~np.asarray(batch.vertex_mask)] == 0)          # padding stays inert
    for got, mesh in zip(unpad(batch, out), three_meshes):
        np.testing.assert_allclose(got.vertices, METHODS[name](mesh).vertices, rtol=1e-9, atol=1e-10)


def test_unpad_restores_every_array(three_meshes):
    batch = pad_batch(three_meshes)
    padded = batch.mesh.vertices.shape[1]
    assert batch.mesh.num_vertices == padded and batch.mesh.num_faces == batch.mesh.faces.shape[1]   # per mesh, not B
    assert batch.mesh.num_edges == batch.mesh.edges.shape[1] and batch.mesh.batch_shape == (len(three_meshes),)
    for got, mesh in zip(unpad(batch), three_meshes):
        for field in ("vertices", "faces", "edges", "face_edges", "src", "dst", "edge_of", "degree"):
            np.testing.assert_array_equal(getattr(got, field), getattr(mesh, field))
        assert float(visual_error(mesh, got)) == 0.0


def test_pad_batch_refuses_bad_input(three_meshes):
    with pytest.raises(ValueError, match="at least one mesh"):
        pad_batch([])
    with pytest.raises(ValueError, match="different dtypes"):
        pad_batch([three_meshes[0], three_meshes[1].astype(np.float32)])
    assert_refused(pad_batch, [np.zeros((3, 3))], param="meshes", message="not a jaxmesh.Mesh", error=TypeError)
    batched = three_meshes[0].with_vertices(np.stack([three_meshes[0].vertices] * 2))
    with pytest.raises(ValueError, match="already batched"):
        pad_batch([batched])
    with pytest.raises(ValueError, match="batched mesh"):
        shard(three_meshes[0])


def _spread(meshes):
    """The meshes at different places and scales, so that a wrong frame shows."""
    return [m.with_vertices(np.asarray(m.vertices) * s + o) for m, s, o in
            zip(meshes, (3.0, 0.01, 250.0), ((0, 0, 0), (5, -2, 1), (-1e3, 7, 0)))]


def test_pack_batch_is_the_disjoint_union_and_unpacks_exactly(three_meshes):
    meshes = _spread(three_meshes)
    packed = pack_batch(meshes)
    offsets = np.cumsum([0] + [m.num_vertices for m in meshes])
    union = jaxmesh.Mesh.from_arrays(np.concatenate([np.asarray(m.vertices) for m in meshes]),
                                     np.concatenate([np.asarray(m.faces) + o for m, o in zip(meshes, offsets)]))
    nv, nf, ne = union.num_vertices, union.num_faces, union.num_edges
    assert packed.mesh.vertices.shape == (nv + 1, 3) and packed.segments == 4       # one padding vertex, one segment
    for field in ("vertices", "faces", "edges", "face_edges", "src", "dst", "edge_of", "degree"):
        got = np.asarray(getattr(packed.mesh, field))
        np.testing.assert_array_equal(got[:len(getattr(union, field))], getattr(union, field))
    assert np.all(np.asarray(packed.mesh.edges)[ne:] == nv) and np.all(np.asarray(packed.mesh.faces)[nf:] == nv)
    np.testing.assert_array_equal(packed.segment, np.repeat([0, 1, 2, 3], [m.num_vertices for m in meshes] + [1]))
    for got, mesh in zip(unpack(packed), meshes):
        for field in ("vertices", "faces", "edges", "face_edges", "src", "dst", "edge_of", "degree"):
            np.testing.assert_array_equal(getattr(got, field), getattr(mesh, field))
    spec = packed_spec((nv + 5, nf + 3, ne + 4), np.float64)
    real = pack_batch(meshes, (nv + 5, nf + 3, ne + 4), segments=8)
    assert jax.tree.map(lambda a: (a.shape, a.dtype), spec) == jax.tree.map(lambda a: (a.shape, a.dtype), real.mesh)
    with pytest.raises(ValueError, match="smaller than the union needs"):
        pack_batch(meshes, (nv, nf, ne + 1))
    with pytest.raises(ValueError, match="too few"):
        pack_batch(meshes, segments=3)
    with pytest.raises(ValueError, match="at least one mesh"):
        pack_batch([])


PACKABLE = sorted(n for n, m in METHODS.items() if m.packable)


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n == "bilateral" else n  # 4 s
                                  for n in PACKABLE])
def test_a_packable_method_on_the_union_gives_each_mesh_its_own_result(three_meshes, name):
    """``Method.packable`` is honest (``local``, or one ``unit`` scaled to 1 per mesh): each
    mesh of the union, in its own frame, gets what
    denoise_in_unit_frame gives it alone; padding stays inert; jit equals eager."""
    meshes = _spread(three_meshes)
    packed = pack_batch(meshes, segments=6)
    for got, mesh in zip(denoise_packed(packed, name, iterations=3), meshes):
        want = denoise_in_unit_frame(mesh, name, iterations=3)
        scale = float(np.ptp(np.asarray(mesh.vertices)))
        np.testing.assert_allclose(got.vertices, want.vertices, rtol=0, atol=1e-12 * scale)
    eager, bad = packed_run(packed.mesh, packed.segment, packed.far, 6, name, iterations=3)
    jitted = jax.jit(lambda m: packed_run(m, packed.segment, packed.far, 6, name, iterations=3))(packed.mesh)
    np.testing.assert_allclose(eager.vertices, jitted[0].vertices, rtol=1e-12, atol=1e-9)
    assert not np.any(bad) and np.all(np.asarray(eager.vertices)[-1] == 0)


def test_a_float32_union_matches_single_float32_calls(three_meshes):
    meshes = [m.astype(np.float32) for m in _spread(three_meshes)]
    packed = pack_batch(meshes)
    assert packed.mesh.vertices.dtype == np.float32
    for got, mesh in zip(denoise_packed(packed, "taubin"), meshes):
        assert got.vertices.dtype == np.float32
        want = denoise_in_unit_frame(mesh, "taubin")
        np.testing.assert_allclose(got.vertices, want.vertices, rtol=0, atol=1e-5 * float(np.ptp(mesh.vertices)))


def test_methods_with_a_global_quantity_are_refused(three_meshes):
    packed = pack_batch(three_meshes)
    assert {"umbrella_flow", "taubin", "hc", "kernel", "cotangent", "bilateral"} <= set(PACKABLE)
    for name in ("cauchy_diffusion", "geometric", "impulse_repair", "cotangent_implicit", "l0"):
        with pytest.raises(ValueError, match="reduces over the whole mesh"):
            denoise_packed(packed, name)


def test_divergence_is_told_per_mesh(three_meshes):
    """One mesh of the union blows up (a method that scales its vertices 1000×): that mesh,
    and only it, is reported, by :func:`diverged` per segment and by denoise_packed."""
    import jax.numpy as jnp

    packed = pack_batch(three_meshes)
    first = three_meshes[0].num_vertices
    second = first + three_meshes[1].num_vertices

    def grow(mesh):
        i = jnp.arange(mesh.num_vertices)[:, None]
        return mesh.with_vertices(jnp.where((i >= first) & (i < second), 1e3, 1.0) * mesh.vertices)

    blow = Method("grow", grow, {}, "test", "test", local=True)
    _, bad = packed_run(packed.mesh, packed.segment, packed.far, packed.segments, blow)
    np.testing.assert_array_equal(bad, [False, True, False, False])
    with pytest.raises(FloatingPointError, match=r"packed mesh\(es\) \[1\]"):
        denoise_packed(packed, blow)
    nan = packed.mesh.with_vertices(packed.mesh.vertices.at[first + 2, 1].set(jnp.nan))
    np.testing.assert_array_equal(diverged(packed.mesh, nan, far=packed.far, segment=packed.segment, segments=4),
                                  [False, True, False, False])


SHARDING_SCRIPT = textwrap.dedent("""
    import jax, numpy as np
    jax.config.update("jax_enable_x64", True)
    import jaxmesh
    from jaxmesh.batch import pad_batch, shard, unpad
    from jaxmesh.denoise import kernel_diffusion
    assert jax.device_count() == 4, jax.devices()
    clean = jaxmesh.normalize(jaxmesh.data.load_sample("spot", dtype=np.float64))
    noisy = jaxmesh.add_noise(clean.with_vertices(np.stack([clean.vertices] * 8)), 0.3, 0)
    ref = kernel_diffusion(noisy, 0.4, 3).vertices
    sharded = shard(noisy)
    assert len(sharded.vertices.sharding.device_set) == 4
    out = jax.jit(lambda m: kernel_diffusion(m, 0.4, 3))(sharded).vertices
    assert len(out.sharding.device_set) == 4
    np.testing.assert_allclose(out, ref, rtol=1e-10, atol=1e-12)
    # a padded batch of different meshes, every array split
    meshes = [noisy.with_vertices(noisy.vertices[0]), jaxmesh.data.load_sample("bunny", dtype=np.float64)]
    batch = pad_batch(meshes * 2)
    out = jax.jit(jax.vmap(lambda m: kernel_diffusion(m, 0.4, 2)))(shard(batch).mesh)
    for got, m in zip(unpad(batch, out), meshes * 2):
        np.testing.assert_allclose(got.vertices, kernel_diffusion(m, 0.4, 2).vertices, rtol=1e-9, atol=1e-12)
    try:
        shard(noisy.with_vertices(noisy.vertices[:6]))
    except ValueError as e:
        assert "not a multiple of the 4 devices" in str(e)
    else:
        raise AssertionError("a batch of 6 over 4 devices must be refused")
    print("SHARDED OK")
""")


@pytest.mark.slow   # a fresh Python process with four host devices (~10 s)
def test_batch_shards_over_four_cpu_devices():
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4", JAX_PLATFORMS="cpu")
    res = subprocess.run([sys.executable, "-c", SHARDING_SCRIPT], env=env, capture_output=True,
                         text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "SHARDED OK" in res.stdout

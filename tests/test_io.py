"""Reading and writing: order kept, atomic no-clobber writes, bad files refused."""

import os

import numpy as np
import pytest

import jaxmesh
from jaxmesh import MeshFileError, MeshWarning
from conftest import shared_mesh_path, tetrahedron_arrays


@pytest.fixture
def tet64():
    return jaxmesh.Mesh.from_arrays(*tetrahedron_arrays(), dtype=np.float64)


@pytest.mark.parametrize("fmt", ["ply", "obj", "off"])
def test_round_trip_keeps_vertex_order_exactly(tmp_path, spot, fmt):
    out = jaxmesh.save(spot, tmp_path / f"spot.{fmt}")
    back = jaxmesh.load(out, dtype=np.float64)
    np.testing.assert_array_equal(np.asarray(back.faces), np.asarray(spot.faces))
    rtol = 0 if fmt == "ply" else 1e-15  # text formats round-trip to the last digit
    np.testing.assert_allclose(np.asarray(back.vertices), np.asarray(spot.vertices), rtol=rtol, atol=1e-15)


def test_stl_round_trip_merges_by_default(tmp_path, tet64):
    out = jaxmesh.save(tet64, tmp_path / "t.stl")
    back = jaxmesh.load(out, dtype=np.float64)
    assert (back.num_vertices, back.num_faces, back.num_edges) == (4, 4, 6)
    raw = jaxmesh.load(out, merge_duplicates=False, dtype=np.float64)
    assert raw.num_vertices == 12  # STL stores every corner


def test_load_shared_mesh_keeps_file_order():
    import trimesh

    p = shared_mesh_path("cow.ply")
    m = jaxmesh.load(p, dtype=np.float64)
    tm = trimesh.load(p, process=False)
    np.testing.assert_array_equal(np.asarray(m.vertices), tm.vertices)
    np.testing.assert_array_equal(np.asarray(m.faces), tm.faces)


def test_never_overwrites_unless_asked(tmp_path, tet64):
    target = tmp_path / "t.ply"
    target.write_bytes(b"precious")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        jaxmesh.save(tet64, target)
    assert target.read_bytes() == b"precious"
    jaxmesh.save(tet64, target, overwrite=True)
    assert jaxmesh.load(target).num_faces == 4
    assert sorted(os.listdir(tmp_path)) == ["t.ply"]  # no temporary left behind


def test_failed_write_leaves_nothing(tmp_path, tet64):
    with pytest.raises(MeshFileError, match="does not exist"):
        jaxmesh.save(tet64, tmp_path / "missing" / "t.ply")
    with pytest.raises(MeshFileError, match="unsupported format"):
        jaxmesh.save(tet64, tmp_path / "t.xyz")
    bad = tet64.with_vertices(tet64.vertices.at[0, 0].set(np.nan))
    with pytest.raises(ValueError, match="non-finite"):
        jaxmesh.save(bad, tmp_path / "t.ply")
    assert os.listdir(tmp_path) == []


def test_polygons_are_triangulated_with_a_warning_or_refused(tmp_path):
    p = tmp_path / "quad.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    with pytest.warns(MeshWarning, match="1 of 1 faces are polygons; fan-triangulated into 2"):
        m = jaxmesh.load(p)
    assert m.num_faces == 2
    with pytest.raises(MeshFileError, match="polygons"):
        jaxmesh.load(p, triangulate=False)
    off = tmp_path / "quad.off"
    off.write_text("OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n")
    with pytest.warns(MeshWarning, match="polygons"):
        assert jaxmesh.load(off).num_faces == 2


def test_truncated_garbage_empty_and_missing_files(tmp_path):
    src = shared_mesh_path("spot.ply").read_bytes()
    trunc = tmp_path / "trunc.ply"
    trunc.write_bytes(src[: len(src) // 2])
    with pytest.raises(MeshFileError, match=r"trunc.ply: cannot read as PLY"):
        jaxmesh.load(trunc)
    garbage = tmp_path / "g.off"
    garbage.write_text("this is not a mesh\n")
    with pytest.raises(MeshFileError, match="g.off"):
        jaxmesh.load(garbage)
    empty = tmp_path / "e.obj"
    empty.write_text("")
    with pytest.raises(MeshFileError, match="empty file"):
        jaxmesh.load(empty)
    nofaces = tmp_path / "n.obj"
    nofaces.write_text("v 0 0 0\nv 1 0 0\n")
    with pytest.raises(MeshFileError, match="no triangles"):
        jaxmesh.load(nofaces)
    with pytest.raises(MeshFileError, match="no such file"):
        jaxmesh.load(tmp_path / "absent.ply")
    with pytest.raises(MeshFileError, match="unsupported format"):
        jaxmesh.load(tmp_path / "x.dae")


def test_bad_values_in_files_are_named(tmp_path):
    p = tmp_path / "nan.obj"
    p.write_text("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(MeshFileError, match="vertex 1 has a non-finite coordinate"):
        jaxmesh.load(p)
    q = tmp_path / "range.off"
    q.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    with pytest.raises(MeshFileError, match="range.off: .*range"):
        jaxmesh.load(q)


def test_merge_duplicates_on_a_real_defect_mesh():
    p = shared_mesh_path("defects/teapot.ply")
    raw = jaxmesh.load(p)
    assert jaxmesh.mesh_info(raw)["duplicate_vertices"] == 403
    merged = jaxmesh.load(p, merge_duplicates=True)
    assert merged.num_vertices == raw.num_vertices - 403
    assert jaxmesh.mesh_info(merged)["duplicate_vertices"] == 0
    # first occurrences keep their relative order
    v = np.asarray(raw.vertices)
    _, first = np.unique(v, axis=0, return_index=True)
    np.testing.assert_array_equal(np.asarray(merged.vertices), v[np.sort(first)])

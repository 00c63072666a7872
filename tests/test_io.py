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


def _half_of_spot() -> bytes:
    data = jaxmesh.data.sample_path("spot").read_bytes()
    return data[: len(data) // 2]


BAD_FILES = [  # (file name, content or None for absent, expected message)
    ("trunc.ply", _half_of_spot, r"trunc.ply: cannot read as PLY"),
    ("g.off", "this is not a mesh\n", r"g.off"),
    ("e.obj", "", r"empty file"),
    ("n.obj", "v 0 0 0\nv 1 0 0\n", r"no triangles"),
    ("absent.ply", None, r"no such file"),
    ("x.dae", None, r"unsupported format"),
    ("nan.obj", "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n", r"vertex 1 has a non-finite coordinate"),
    ("range.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n", r"range.off: .*range"),
]


@pytest.mark.parametrize("name,content,message", BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_bad_files_get_a_clear_error(tmp_path, name, content, message):
    p = tmp_path / name
    if callable(content):
        content = content()
    if isinstance(content, bytes):
        p.write_bytes(content)
    elif content is not None:
        p.write_text(content)
    with pytest.raises(MeshFileError, match=message):
        jaxmesh.load(p)


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

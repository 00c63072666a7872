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


def _binary_ply(vertices, faces, order="<", vertex_props=(("float", "x"), ("float", "y"), ("float", "z")),
                face_before=(), face_after=(), count="uchar", index="int", list_name="vertex_indices",
                before=None, after=None):
    """A binary PLY of any layout, written field by field (independent of both readers)."""
    types = {"uchar": "u1", "char": "i1", "ushort": "u2", "short": "i2", "int": "i4", "uint": "u4",
             "float": "f4", "double": "f8"}
    lines = ["ply", f"format binary_{'little' if order == '<' else 'big'}_endian 1.0", "comment test"]
    body = b""
    elements = ([before] if before else []) + ["vertex", "face"] + ([after] if after else [])
    rng = np.random.default_rng(0)
    for el in elements:
        if el == "vertex":
            lines.append(f"element vertex {len(vertices)}")
            lines += [f"property {t} {n}" for t, n in vertex_props]
            dt = np.dtype([(n, order + types[t]) for t, n in vertex_props])
            rec = np.zeros(len(vertices), dt)
            for k, n in enumerate("xyz"):
                rec[n] = vertices[:, k]
            for t, n in vertex_props:
                if n not in "xyz":
                    rec[n] = rng.integers(0, 100, len(vertices))
        elif el == "face":
            lines.append(f"element face {len(faces)}")
            lines += [f"property {t} {n}" for t, n in face_before]
            lines.append(f"property list {count} {index} {list_name}")
            lines += [f"property {t} {n}" for t, n in face_after]
            dt = np.dtype([(n, order + types[t]) for t, n in face_before] + [("n", order + types[count]),
                          ("i", order + types[index], (3,))] + [(n, order + types[t]) for t, n in face_after])
            rec = np.zeros(len(faces), dt)
            rec["n"], rec["i"] = 3, faces
        else:
            name, n = el
            lines += [f"element {name} {n}", "property int a", "property uchar b"]
            rec = np.zeros(n, np.dtype([("a", order + "i4"), ("b", "u1")]))
        body += rec.tobytes()
    return ("\n".join(lines) + "\nend_header\n").encode() + body


@pytest.mark.parametrize("layout", [
    {},
    {"order": ">"},
    {"vertex_props": (("double", "x"), ("double", "y"), ("double", "z"), ("float", "nx"), ("uchar", "red"))},
    {"vertex_props": (("uchar", "red"), ("float", "z"), ("float", "x"), ("float", "y"))},
    {"count": "uint", "index": "uint", "list_name": "vertex_index"},
    {"count": "uchar", "index": "ushort", "face_before": (("int", "tag"),), "face_after": (("uchar", "alpha"),)},
    {"before": ("camera", 2), "after": ("edge", 5), "order": ">"},
])
def test_binary_ply_layouts_read_as_trimesh_reads_them(tmp_path, spot, layout):
    """The numpy fast path (:mod:`jaxmesh._ply`) on every common binary layout equals
    trimesh's general reader, and jaxmesh.load takes the fast path for it."""
    import trimesh

    from jaxmesh import _ply

    v = np.asarray(spot.vertices, np.float64) * 3 - 1
    f = np.asarray(spot.faces)
    data = _binary_ply(v, f, **layout)
    path = tmp_path / "t.ply"
    path.write_bytes(data)
    fast = _ply.read_binary(data)
    assert fast is not None
    tm = trimesh.load(path, file_type="ply", process=False, maintain_order=True, force="mesh")
    np.testing.assert_array_equal(fast[0], np.asarray(tm.vertices, np.float64))
    np.testing.assert_array_equal(fast[1], np.asarray(tm.faces))
    m = jaxmesh.load(path, dtype=np.float64)
    np.testing.assert_array_equal(np.asarray(m.vertices), fast[0])
    np.testing.assert_array_equal(np.asarray(m.faces), fast[1])


def test_other_ply_layouts_fall_back_to_the_general_reader(tmp_path):
    """Polygons, ASCII and two lists per face are not the fast layout: read_binary
    declines them (None) and load still reads them through trimesh."""
    from jaxmesh import _ply

    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    quad = (b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty double x\nproperty double y\n"
            b"property double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
            + v.tobytes() + bytes([4]) + np.arange(4, dtype="<i4").tobytes())
    tri = _binary_ply(v, np.array([[0, 1, 2], [0, 2, 3]]))
    two_lists = tri.replace(b"property list uchar int vertex_indices\n",
                            b"property list uchar int vertex_indices\nproperty list uchar float texcoord\n")
    ascii_ply = (b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                 b"element face 2\nproperty list uchar int vertex_indices\nend_header\n"
                 b"0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n")
    for data in (quad, two_lists, ascii_ply):
        assert _ply.read_binary(data) is None
    (tmp_path / "q.ply").write_bytes(quad)
    with pytest.warns(MeshWarning, match="polygons"):
        m = jaxmesh.load(tmp_path / "q.ply")
    assert m.num_faces == 2
    (tmp_path / "a.ply").write_bytes(ascii_ply)
    assert jaxmesh.load(tmp_path / "a.ply").num_faces == 2


def _obj_variants(seed: int) -> bytes:
    """A small OBJ, plain or with one of the irregularities the strict reader judges line by line."""
    rng = np.random.default_rng(seed)
    nv = int(rng.integers(3, 7))
    lines = [f"v {' '.join(repr(float(x)) for x in rng.normal(size=3))}" for _ in range(nv)]
    lines += [f"f {' '.join(str(int(i)) for i in rng.choice(np.arange(1, nv + 1), 3, replace=False))}"
              for _ in range(int(rng.integers(1, 5)))]
    extras = ["# a comment", "", "   ", "vn 0 0 1", "  vt 0 0", "g#x", "s off", "usemtl m", "foo 1", "vn\x0b0 0 1",
              "o\x0cname", "\x1cvn 0 0 1", "vnn 1", "averyveryveryverylongkeyword x", "#", "v 1 2", "v 1 2 3 4",
              "v 1 2 3 # c", "v  1 2 3", "v 1 2 3 ", "f 1 2", "f 0 1 2", "f -1 -2 -3", "f 1 2 3 4", "f 1/1/1 2//2 3/3",
              "f 1 2 99", "f /1 2 3", "v 1e0 1_0 +2", "v nan 0 0", "f 1 2 3\x0c", "v 1\xa02 3 4", "l 1 2",
              " " * 18 + "foo 1", " " * 18 + "vn 0 0 1", "usemtl_averyverylongname x"]
    for _ in range(int(rng.integers(0, 4))):
        lines.insert(int(rng.integers(0, len(lines) + 1)), extras[int(rng.integers(len(extras)))])
    end = ["\n", "\r\n"][int(rng.integers(2))]
    text = end.join(lines) + (end if rng.random() < 0.9 else "")
    if rng.random() < 0.1:
        text = text.replace(" ", "\t", 1)
    return text.encode("utf-8")


def test_the_plain_obj_fast_path_reads_every_file_as_the_line_reader_does(monkeypatch):
    """The numpy reading of plain OBJ files (jaxmesh._meshtext._plain_obj) against the line-by-line
    reader on 600 generated files, irregular lines included: the same arrays, or the same error."""
    from jaxmesh import _meshtext

    def outcome(data):
        try:
            v, f, records, polys = _meshtext.read_obj(data)
            return "ok", v.tobytes(), f.tobytes(), v.shape, f.shape, records, polys
        except ValueError as err:
            return "error", str(err)

    fast_taken = 0
    for seed in range(600):
        data = _obj_variants(seed)
        fast = outcome(data)
        fast_taken += _meshtext._plain_obj(data) is not None
        with monkeypatch.context() as m:
            m.setattr(_meshtext, "_plain_obj", lambda data: None)
            assert outcome(data) == fast, data
    assert 100 < fast_taken < 600          # both paths were exercised

"""Attributes kept through a change of positions (jaxmesh.attributes, save(attributes=)):
a textured, coloured OBJ and coloured PLY files (binary and ASCII) come back byte-equal but for
their positions and normals, which are checked against plain numpy references."""

import warnings

import numpy as np
import pytest
import trimesh

import jaxmesh
from jaxmesh.cli import main
from jaxmesh.denoise import METHODS, denoise


def _sphere():
    s = trimesh.creation.icosphere(subdivisions=2)
    rng = np.random.default_rng(0)
    v = s.vertices * (1 + 0.02 * rng.standard_normal((len(s.vertices), 1)))
    return v, np.asarray(s.faces), rng


def _quad_pair(faces):
    """Two triangles (a, b, c), (a, c, d) whose union is the quad (a, b, c, d), and their rows."""
    for i, (a, b, c) in enumerate(faces.tolist()):
        for j, f in enumerate(faces.tolist()):
            if j != i and f[0] == a and f[1] == c:
                return i, j, [a, b, c, f[2]]
    raise AssertionError("no fan pair")


def _textured_obj(path):
    """An OBJ with colours on its v lines, vt, vn, materials, groups, comments and one quad."""
    v, f, rng = _sphere()
    i, j, quad = _quad_pair(f)
    records = [list(r) for k, r in enumerate(f.tolist()) if k not in (i, j)]
    records.insert(i, quad)
    lines = ["# a textured scan", "mtllib scan.mtl", "o scan"]
    lines += ["v %.17g %.17g %.17g %.6f %.6f %.6f" % (*p, *c) for p, c in zip(v, rng.random((len(v), 3)))]
    lines += ["vt %.6f %.6f" % tuple(t) for t in rng.random((len(v), 2))]
    lines += ["vn 0 0 1"] * len(v) + ["vn 1 0 0"]                        # stale; the last one unreferenced
    lines += ["usemtl skin", "g body", "s 1"]
    lines += ["f " + " ".join(f"{k + 1}/{k + 1}/{k + 1}" for k in r) for r in records]
    path.write_text("\n".join(lines) + "\n")
    return records


def _load(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", jaxmesh.MeshWarning)         # the quad is fan-triangulated
        return jaxmesh.load(path)


def _area_normals(v, polygons):
    """Σ over each vertex's polygons of their vector areas (½ Σ fan cross products), normalised."""
    n = np.zeros_like(v)
    for r in polygons:
        area = sum(np.cross(v[r[k]] - v[r[0]], v[r[k + 1]] - v[r[0]]) for k in range(1, len(r) - 1)) / 2
        for k in r:
            n[k] += area
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def _moved(mesh):
    return denoise(mesh, "taubin", iterations=3)


def test_a_textured_obj_keeps_every_line_but_its_positions_and_normals(tmp_path):
    src, out = tmp_path / "scan.obj", tmp_path / "out.obj"
    records = _textured_obj(src)
    mesh = _load(src)
    attributes = jaxmesh.read_attributes(src)
    assert set(attributes.kinds) >= {"vertex colours", "texture coordinates", "normals", "materials",
                                     "corner indices", "polygons", "groups"}
    result = _moved(mesh)
    jaxmesh.save(result, out, attributes=attributes)
    before, after = src.read_text().split("\n"), out.read_text().split("\n")
    assert len(before) == len(after)
    x = np.asarray(result.vertices)
    assert not np.allclose(x, mesh.vertices)
    v_rows = [k for k, line in enumerate(before) if line.startswith("v ")]
    vn_rows = [k for k, line in enumerate(before) if line.startswith("vn ")]
    for k, (a, b) in enumerate(zip(before, after)):
        if k not in v_rows and k not in vn_rows[:-1]:
            assert a == b, k                                          # vt, f a/b/c, materials, the unused vn
    for row, k in enumerate(v_rows):
        tokens = after[k].split()
        assert tokens[4:] == before[k].split()[4:]                    # the colours, as written
        np.testing.assert_array_equal(np.array(tokens[1:4], float), x[row])
    normals = np.array([after[k].split()[1:] for k in vn_rows[:-1]], float)
    np.testing.assert_allclose(normals, _area_normals(x, records), atol=1e-12)
    np.testing.assert_array_equal(_load(out).vertices, x)


def _coloured_ply(path, ascii: bool):
    """A PLY with float32 x y z, nx ny nz, uchar colours, a quality and a face texcoord list."""
    v, f, rng = _sphere()
    vt = np.dtype([(c, "<f4") for c in ("x", "y", "z", "nx", "ny", "nz")] + [(c, "u1") for c in "rgb"]
                  + [("quality", "<f4")])
    rec = np.zeros(len(v), vt)
    for i, c in enumerate("xyz"):
        rec[c] = v[:, i]
    rec["nz"] = 1
    for c in "rgb":
        rec[c] = rng.integers(0, 256, len(v))
    rec["quality"] = rng.random(len(v))
    uv = rng.random((len(f), 6)).astype("<f4")
    head = (f"ply\nformat {'ascii' if ascii else 'binary_little_endian'} 1.0\ncomment TextureFile skin.png\n"
            f"element vertex {len(v)}\n" + "".join(f"property float {c}\n" for c in ("x", "y", "z", "nx", "ny", "nz"))
            + "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty float quality\n"
            f"element face {len(f)}\nproperty list uchar int vertex_indices\nproperty list uchar float texcoord\n"
            "end_header\n")
    if ascii:
        body = "".join(" ".join([*(repr(float(r[c])) for c in ("x", "y", "z", "nx", "ny", "nz")),
                                 *(str(int(r[c])) for c in "rgb"), repr(float(r["quality"]))]) + "\n" for r in rec)
        body += "".join(f"3 {a} {b} {c} 6 " + " ".join(repr(float(t)) for t in u) + "\n" for (a, b, c), u in zip(f, uv))
        path.write_bytes(head.encode() + body.encode())
    else:
        face = np.zeros(len(f), [("n", "u1"), ("i", "<i4", 3), ("m", "u1"), ("t", "<f4", 6)])
        face["n"], face["i"], face["m"], face["t"] = 3, f, 6, uv
        path.write_bytes(head.encode() + rec.tobytes() + face.tobytes())
    return rec, f, len(head)


@pytest.mark.parametrize("ascii", [False, True], ids=["binary", "ascii"])
def test_a_coloured_ply_keeps_every_property_but_positions_and_normals(tmp_path, ascii):
    src, out = tmp_path / "scan.ply", tmp_path / "out.ply"
    rec, faces, head = _coloured_ply(src, ascii)
    mesh = jaxmesh.load(src)
    attributes = jaxmesh.read_attributes(src)
    assert set(attributes.kinds) == {"vertex colours", "normals", "vertex property 'quality'",
                                     "texture coordinates", "texture file"}
    result = _moved(mesh)
    jaxmesh.save(result, out, attributes=attributes)
    data, x = out.read_bytes(), np.asarray(result.vertices)
    assert data[:head] == src.read_bytes()[:head]
    if ascii:
        lines = data[head:].decode().split("\n")
        got = np.array([line.split() for line in lines[:len(rec)]], float)
        assert lines[len(rec):] == src.read_bytes()[head:].decode().split("\n")[len(rec):]
        np.testing.assert_array_equal(got[:, 6:9], np.stack([rec[c] for c in "rgb"], 1))
        np.testing.assert_array_equal(got[:, 9].astype(np.float32), rec["quality"])
        xyz, normals = got[:, :3], got[:, 3:6]
    else:
        new = np.frombuffer(data, rec.dtype, len(rec), head)
        assert data[head + rec.nbytes:] == src.read_bytes()[head + rec.nbytes:]      # the faces and their UVs
        for c in ("r", "g", "b", "quality"):
            np.testing.assert_array_equal(new[c], rec[c])
        xyz, normals = np.stack([new[c] for c in "xyz"], 1), np.stack([new[c] for c in ("nx", "ny", "nz")], 1)
    np.testing.assert_allclose(xyz, x.astype(np.float32), rtol=2e-7)            # the file's float32
    np.testing.assert_allclose(normals, _area_normals(x, faces.tolist()), atol=1e-6)


def test_plain_files_carry_nothing_and_refusals_name_the_problem(tmp_path, tetra):
    for name in ("a.obj", "a.ply", "a.off"):
        jaxmesh.save(tetra, tmp_path / name)
        assert jaxmesh.read_attributes(tmp_path / name) is None
    src = tmp_path / "scan.ply"
    _coloured_ply(src, ascii=False)
    attributes = jaxmesh.read_attributes(src)
    with pytest.raises(jaxmesh.MeshFileError, match="OBJ cannot hold them"):
        jaxmesh.save(jaxmesh.load(src), tmp_path / "out.obj", attributes=attributes)
    with pytest.raises(jaxmesh.MeshFileError, match="the mesh has 4 vertices, the file .* 162"):
        jaxmesh.save(tetra, tmp_path / "out.ply", attributes=attributes)
    listed = tmp_path / "listed.ply"
    listed.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                      "property float z\nproperty list uchar int tags\nelement face 1\n"
                      "property list uchar int vertex_indices\nend_header\n0 0 0 0\n1 0 0 0\n0 1 0 0\n3 0 1 2\n")
    with pytest.raises(ValueError, match="list properties"):
        jaxmesh.read_attributes(listed)


def test_the_cli_keeps_attributes_or_says_it_cannot(tmp_path, capsys):
    src = tmp_path / "scan.ply"
    rec, _, head = _coloured_ply(src, ascii=False)
    assert main(["denoise", str(src), str(tmp_path / "out.ply"), "--method", "taubin", "--iterations", "2"]) == 0
    new = np.frombuffer((tmp_path / "out.ply").read_bytes(), rec.dtype, len(rec), head)
    np.testing.assert_array_equal(new[["r", "g", "b", "quality"]], rec[["r", "g", "b", "quality"]])
    assert not np.array_equal(new["x"], rec["x"])
    capsys.readouterr()
    assert main(["noise", str(src), str(tmp_path / "out.off"), "--sigma", "0.1"]) == 0
    err = capsys.readouterr().err
    assert "carries normals, texture coordinates, texture file, vertex colours" in err and "write .ply" in err


@pytest.mark.slow       # one compile per method
@pytest.mark.parametrize("name", sorted(METHODS))
def test_every_method_keeps_the_obj_and_ply_attributes(tmp_path, name):
    src, out = tmp_path / "scan.obj", tmp_path / "out.obj"
    _textured_obj(src)
    mesh = _load(src)
    result = denoise(mesh, name)
    jaxmesh.save(result, out, attributes=jaxmesh.read_attributes(src))
    keep = lambda text: [s for s in text.split("\n") if not s.startswith(("v ", "vn "))]  # noqa: E731
    assert keep(out.read_text()) == keep(src.read_text())
    colours = lambda text: [s.split()[4:] for s in text.split("\n") if s.startswith("v ")]  # noqa: E731
    assert colours(out.read_text()) == colours(src.read_text())
    assert not np.allclose(_load(out).vertices, mesh.vertices)
    src, out = tmp_path / "scan.ply", tmp_path / "out.ply"
    rec, _, head = _coloured_ply(src, ascii=False)
    mesh = jaxmesh.load(src)
    jaxmesh.save(denoise(mesh, name), out, attributes=jaxmesh.read_attributes(src))
    data = out.read_bytes()
    new = np.frombuffer(data, rec.dtype, len(rec), head)
    np.testing.assert_array_equal(new[["r", "g", "b", "quality"]], rec[["r", "g", "b", "quality"]])
    assert data[head + rec.nbytes:] == src.read_bytes()[head + rec.nbytes:]
    assert not np.allclose(np.stack([new[c] for c in "xyz"], 1), np.stack([rec[c] for c in "xyz"], 1))


def test_a_dataset_run_keeps_each_inputs_attributes(tmp_path):
    src, out = tmp_path / "in", tmp_path / "out"
    src.mkdir()
    rec, _, head = _coloured_ply(src / "scan.ply", ascii=False)
    _textured_obj(src / "tex.obj")
    assert main(["denoise", "--out-dir", str(out), str(src / "scan.ply"), str(src / "tex.obj"),
                 "--method", "taubin", "--iterations", "2"]) == 0
    new = np.frombuffer((out / "scan.ply").read_bytes(), rec.dtype, len(rec), head)
    np.testing.assert_array_equal(new[["r", "g", "b", "quality"]], rec[["r", "g", "b", "quality"]])
    assert not np.array_equal(new["x"], rec["x"])
    keep = lambda p: [s for s in p.read_text().split("\n") if not s.startswith(("v ", "vn "))]  # noqa: E731
    assert keep(out / "tex.obj") == keep(src / "tex.obj")


@pytest.mark.parametrize("text,plain", [
    ("v 1 2 3\nv 0 1 0\nv 0 0 1\nf 1 2 3\n", True), ("# c\n\nv 1  2 3\nv 0 1 0\nv 0 0 1\nf 1 2 3\n", True),
    ("v 1 2 3 0.5 0.5 0.5\nv 0 1 0\nv 0 0 1\nf 1 2 3\n", False), ("v 1 2 3\nv 0 1 0\nv 0 0 1\nvt 0 0\nf 1 2 3\n", False),
    ("v 1 2 3\nv 0 1 0\nv 0 0 1\ng x\nf 1 2 3\n", False), ("v 1 2 3\nv 0 1 0\nv 0 0 1\nf 1/1 2/2 3/3\n", False)])
def test_the_vectorised_plain_obj_check_agrees_with_the_line_reading(tmp_path, text, plain):
    from jaxmesh._meshtext import only_positions_and_triangles

    path = tmp_path / "m.obj"
    path.write_text(text)
    assert only_positions_and_triangles(text.encode()) == plain
    assert (jaxmesh.read_attributes(path) is None) == plain

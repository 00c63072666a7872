"""Topology summaries: hand cases, and the shared meshes against MANIFEST.md."""

import re

import numpy as np
import pytest

import jaxmesh
from jaxmesh import topology as T
from conftest import SHARED_MESHES, grid_arrays, torus_arrays


def test_hand_cases(tetra, octa, grid, triangle):
    assert T.euler_characteristic(tetra) == 2 and T.genus(tetra) == 0
    assert T.euler_characteristic(octa) == 2
    assert T.euler_characteristic(triangle) == 1 and len(T.boundary_edges(triangle)) == 3
    # 5 x 4 vertices grid (4 x 3 cells): boundary is 2 * (4 + 3) edges, one loop, a disk
    assert len(T.boundary_edges(grid)) == 14 and T.boundary_loop_count(grid) == 1
    assert T.genus(grid) == 0 and T.connected_components(grid)[0] == 1
    assert T.is_consistently_oriented(tetra)


def test_torus_and_two_components(tetra):
    t = jaxmesh.Mesh.from_arrays(*torus_arrays())
    assert T.euler_characteristic(t) == 0 and T.genus(t) == 1
    v, f = grid_arrays(2, 2)
    two = jaxmesh.Mesh.from_arrays(np.vstack([v, v + 10]), np.vstack([f, f + len(v)]))
    assert T.connected_components(two)[0] == 2 and T.genus(two) is None


def test_non_manifold_vertex_bowtie():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]])
    m = jaxmesh.Mesh.from_arrays(v, np.array([[0, 1, 2], [0, 3, 4]]))
    np.testing.assert_array_equal(T.non_manifold_vertices(m), [0])
    assert len(T.non_manifold_edges(m)) == 0 and T.genus(m) is None


def test_inconsistent_orientation():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    flipped = jaxmesh.Mesh.from_arrays(v, np.array([[0, 1, 2], [1, 2, 3]]))
    assert not T.is_consistently_oriented(flipped)
    ok = jaxmesh.Mesh.from_arrays(v, np.array([[0, 1, 2], [2, 1, 3]]))
    assert T.is_consistently_oriented(ok)


def _disagreeing_edges(faces, mesh) -> int:
    """Two-face edges whose faces run them the same way (a plain loop over the faces)."""
    seen = {}
    for f in np.asarray(faces).tolist():
        for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])):
            seen.setdefault((min(a, b), max(a, b)), []).append((a, b))
    return sum(1 for runs in seen.values() if len(runs) == 2 and runs[0] == runs[1])


def _reoriented(mesh):
    flips = T.orientation_flips(np.asarray(mesh.faces), np.asarray(mesh.face_edges), mesh.num_edges)
    f = np.array(mesh.faces)
    f[flips] = f[flips][:, [0, 2, 1]]
    return flips, f


def test_orientation_flips_orient_every_orientable_component():
    """A torus and a grid, side by side, with random faces reversed: the flips make the
    windings agree on every edge (checked by a loop and by trimesh), reversing the reversed
    faces or their complement in each component; a consistent mesh gets none."""
    import trimesh

    v1, f1 = torus_arrays()
    v2, f2 = grid_arrays(5, 4)
    v, f = np.vstack([v1, v2 + 10]), np.vstack([f1, f2 + len(v1)])
    mesh = jaxmesh.Mesh.from_arrays(v, f)
    assert not _reoriented(mesh)[0].any()
    reversed_ = np.random.default_rng(0).random(len(f)) < 0.3
    g = f.copy()
    g[reversed_] = g[reversed_][:, [0, 2, 1]]
    messy = jaxmesh.Mesh.from_arrays(v, g)
    assert _disagreeing_edges(g, messy) > 50 and not T.is_consistently_oriented(messy)
    flips, fixed = _reoriented(messy)
    assert _disagreeing_edges(fixed, messy) == 0
    assert T.is_consistently_oriented(jaxmesh.Mesh.from_arrays(v, fixed))
    assert trimesh.Trimesh(v, fixed, process=False).is_winding_consistent
    for part in (slice(0, len(f1)), slice(len(f1), None)):      # per component: the reversal or its complement
        assert (flips[part] == reversed_[part]).all() or (flips[part] != reversed_[part]).all()


def test_orientation_flips_leave_one_edge_of_a_moebius_strip():
    """A Möbius strip of 2n triangles has no consistent winding: whatever the input windings,
    exactly one edge of its ring of faces is left disagreeing."""
    n = 12
    t = np.arange(n) * 2 * np.pi / n
    rows = []
    for s in (-0.3, 0.3):                                   # the strip's two edges, half-twisted
        r = 2 + s * np.cos(t / 2)
        rows.append(np.stack([r * np.cos(t), r * np.sin(t), s * np.sin(t / 2)], 1))
    v = np.vstack(rows)                                    # vertex i: (i < n) lower, (i >= n) upper
    faces = []
    for i in range(n):
        j = (i + 1) % n
        a, b, c, d = i, j, n + i, n + j
        if j == 0:                                         # past the half twist the sides swap: L_n = U_0, U_n = L_0
            b, d = n, 0
        faces += [[a, b, c], [c, b, d]]
    mesh = jaxmesh.Mesh.from_arrays(v, np.array(faces))
    for seed in range(3):
        g = np.array(faces)
        r = np.random.default_rng(seed).random(len(g)) < 0.5
        g[r] = g[r][:, [0, 2, 1]]
        messy = jaxmesh.Mesh.from_arrays(v, g)
        _, fixed = _reoriented(messy)
        assert _disagreeing_edges(fixed, messy) == 1


def manifest_rows():
    path = SHARED_MESHES / "MANIFEST.md"
    if not path.is_file():
        return []
    rows = []
    for line in path.read_text().splitlines():
        c = [x.strip() for x in line.split("|")]
        if len(c) > 10 and c[1].endswith(".ply") and c[2].isdigit():
            rows.append(c)
    return rows


MAIN = [r for r in manifest_rows() if r[7] in ("yes", "no")]
DEFECTS = [r for r in manifest_rows() if r[7] not in ("yes", "no")]


def _require(rows):
    if not rows:
        pytest.skip(f"{SHARED_MESHES}/MANIFEST.md not found: shared meshes absent")


@pytest.mark.parametrize("row", MAIN or [None], ids=lambda r: r[1] if r else "absent")
def test_info_matches_manifest(row):
    _require(MAIN)
    info = jaxmesh.mesh_info(jaxmesh.load(SHARED_MESHES / row[1]))
    expected = dict(vertices=int(row[2]), faces=int(row[3]), edges=int(row[4]),
                    boundary_edges=int(row[5]), components=int(row[6]),
                    watertight=row[7] == "yes", euler_characteristic=int(row[10]))
    assert {k: info[k] for k in expected} == expected
    assert info["mean_edge_length"] == pytest.approx(float(row[8]), rel=1e-5)
    assert info["bbox_diagonal"] == pytest.approx(float(row[9]), rel=1e-5)
    note = {"cow.ply": (False, 1)}.get(row[1], (True, 0))  # MANIFEST: one non-manifold vertex in cow
    assert (info["manifold"], info["non_manifold_vertices"]) == note


@pytest.mark.parametrize("row", DEFECTS or [None], ids=lambda r: r[1] if r else "absent")
def test_defect_info_matches_manifest(row):
    _require(DEFECTS)
    info = jaxmesh.mesh_info(jaxmesh.load(SHARED_MESHES / "defects" / row[1]))
    expected = dict(vertices=int(row[2]), faces=int(row[3]), edges=int(row[4]),
                    boundary_edges=int(row[5]), non_manifold_edges=int(row[6]),
                    duplicate_vertices=int(row[7]), components=int(row[8]), degenerate_faces=int(row[9]))
    assert {k: info[k] for k in expected} == expected


def test_manifest_genus_notes():
    _require(MAIN)
    genus = {}
    for r in MAIN:
        if r[1] in ("eight.ply", "fertility.ply", "spot.ply"):
            genus[r[1]] = T.genus(jaxmesh.load(SHARED_MESHES / r[1]))
    assert genus == {"eight.ply": 2, "fertility.ply": 4, "spot.ply": 0}
    assert re.search(r"genus 4", (SHARED_MESHES / "MANIFEST.md").read_text())


def test_face_adjacency(tetra, grid):
    # every pair of the tetrahedron's 4 faces shares an edge
    np.testing.assert_array_equal(T.face_adjacency(tetra), [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
    # open grid: one pair per interior edge
    interior = grid.num_edges - len(T.boundary_edges(grid))
    pairs = T.face_adjacency(grid)
    assert len(pairs) == interior
    f = np.asarray(grid.faces)
    for a, b in pairs:
        assert len(set(f[a]) & set(f[b])) == 2
    v = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]])
    nm = jaxmesh.Mesh.from_arrays(v, np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))
    np.testing.assert_array_equal(T.face_adjacency(nm), [[0, 1], [0, 2], [1, 2]])

"""jaxmesh.view and `jaxmesh view`: the page's embedded data, its refusals, and the page
drawn by a real headless browser (Chromium), screenshot checked panel by panel."""

import base64
import os
import shutil
import subprocess
from pathlib import Path

import jax
import numpy as np
import pytest
from conftest import assert_refused, octahedron_arrays, tetrahedron_arrays, viewer_config

import jaxmesh
from jaxmesh.view import ramp, vertex_distances, viewer_html, write_viewer

REPO = Path(__file__).resolve().parents[1]


def _decode(b64: str, dtype) -> np.ndarray:
    return np.frombuffer(base64.b64decode(b64), dtype=np.dtype(dtype).newbyteorder("<"))


def test_the_page_embeds_the_meshes_in_the_first_meshs_frame():
    a = jaxmesh.Mesh.from_arrays(*octahedron_arrays())
    b = a.with_vertices(2.0 * a.vertices + 1.0)
    page = viewer_html([("a </script> & <b>", a), ("b", b)], [None, np.arange(6.0)], title="t<1>")
    assert "<title>t&lt;1&gt;</title>" in page and "</script> &" not in page   # labels cannot end the script
    cfg = viewer_config(page)
    pa, pb = cfg["panels"]
    assert pa["label"] == "a </script> & <b>" and (pa["num_vertices"], pa["num_faces"]) == (6, 8)
    v = np.asarray(a.vertices)
    centre, diag = 0.5 * (v.max(0) + v.min(0)), np.linalg.norm(v.max(0) - v.min(0))
    np.testing.assert_allclose(_decode(pa["vertices"], np.float32).reshape(-1, 3), (v - centre) / diag, atol=1e-7)
    np.testing.assert_allclose(_decode(pb["vertices"], np.float32).reshape(-1, 3),
                               (2 * v + 1 - centre) / diag, atol=1e-6)
    np.testing.assert_array_equal(_decode(pa["faces"], np.uint32).reshape(-1, 3), np.asarray(a.faces))
    n = _decode(pa["normals"], np.float32).reshape(-1, 3)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1, atol=1e-6)
    # the scalar: the first panel has none; colours on the shared scale (min .. 99th percentile)
    assert "colors" not in pa
    colors = _decode(pb["colors"], np.uint8).reshape(-1, 3)
    lo, hi = cfg["legend"]["low"], cfg["legend"]["high"]
    assert lo == 0 and hi == pytest.approx(np.percentile(np.arange(6.0), 99))
    np.testing.assert_array_equal(colors, np.round(255 * ramp(np.arange(6.0) / hi)).astype(np.uint8))
    assert cfg["shading"] == "flat"


def test_distances_and_refusals(tmp_path):
    a = jaxmesh.Mesh.from_arrays(*tetrahedron_arrays())
    moved = a.with_vertices(a.vertices.at[0, 2].add(0.5))
    np.testing.assert_allclose(vertex_distances(a, moved), [0.5, 0, 0, 0])
    # no correspondence: the distance to the surface (the octahedron's vertices lie on... itself)
    octa = jaxmesh.Mesh.from_arrays(*octahedron_arrays())
    np.testing.assert_allclose(vertex_distances(octa, octa.with_vertices(octa.vertices))[:3], 0, atol=1e-12)
    far = jaxmesh.Mesh.from_arrays(np.asarray(a.vertices) + np.array([[0, 0, 10.0]]), np.asarray(a.faces))
    assert vertex_distances(octa, far).min() > 8
    with pytest.raises(ValueError, match="at least one mesh"):
        viewer_html([])
    assert_refused(viewer_html, [a], param="meshes", message=r"\(label, jaxmesh.Mesh\) pair", error=TypeError)
    with pytest.raises(ValueError, match="scalar has shape"):
        viewer_html([("a", a)], [np.zeros(3)])
    with pytest.raises(ValueError, match="non-finite"):
        viewer_html([("a", a)], [np.array([0, 1, np.nan, 2])])
    with pytest.raises(ValueError, match="single meshes"):
        viewer_html([("batch", a.with_vertices(np.stack([np.asarray(a.vertices)] * 2)))])
    out = tmp_path / "p.html"
    write_viewer(out, [("a", a)])
    with pytest.raises(FileExistsError):
        write_viewer(out, [("a", a)])
    write_viewer(out, [("a", a), ("m", moved)], overwrite=True)
    assert len(viewer_config(out.read_text())["panels"]) == 2


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("no Chromium on PATH (Debian: apt-get install chromium): the browser test needs one")


def _browser(page: Path, *args: str) -> subprocess.CompletedProcess:
    argv = [_chromium(), "--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
            "--enable-logging=stderr", "--v=0", "--hide-scrollbars", "--virtual-time-budget=10000", *args,
            page.resolve().as_uri()]
    return subprocess.run(argv, capture_output=True, text=True, timeout=120)


def test_a_real_browser_draws_every_panel(tmp_path):
    """A shipped sample, noisy and denoised, coloured by the distance to the clean one:
    Chromium loads the page offline, every panel has drawn pixels, the page reports
    ``data-status="drawn"`` and logs no error.  JAXMESH_DOCS_IMAGES=1 draws the bunny
    and writes the screenshot to docs/images/view-bunny.png (the one the docs show)."""
    docs = os.environ.get("JAXMESH_DOCS_IMAGES") == "1"
    name = "bunny" if docs else "spot"     # the docs show the bunny; spot (12x smaller) is as good a check
    clean = jaxmesh.data.load_sample(name, dtype="float64")
    noisy = jaxmesh.add_noise(clean, 0.3, jax.random.PRNGKey(0))
    out = jaxmesh.denoise.denoise(noisy, "taubin", iterations=10)
    page = tmp_path / f"{name}.html"
    write_viewer(page, [("noisy (σ = 0.3 ℓ̄)", noisy), ("denoised (Taubin, 10 pairs)", out)],
                 [vertex_distances(clean, noisy), vertex_distances(clean, out)], scalar_label="distance to clean",
                 title=f"jaxmesh view: the shipped {name}")
    dom = _browser(page, "--dump-dom")
    assert dom.returncode == 0, dom.stderr[-2000:]
    assert 'data-status="drawn"' in dom.stdout, dom.stdout[-3000:] + dom.stderr[-3000:]
    shot = tmp_path / "shot.png"
    run = _browser(page, f"--screenshot={shot}", "--window-size=1200,560")
    assert run.returncode == 0 and shot.is_file(), run.stderr[-2000:]
    logged = [line for line in (dom.stderr + run.stderr).splitlines() if "CONSOLE" in line]
    assert not [line for line in logged if "error" in line.lower() or "uncaught" in line.lower()], logged
    import matplotlib.image

    img = matplotlib.image.imread(str(shot))[..., :3]
    h, w, _ = img.shape
    drawn = np.any(img < 0.9, axis=-1)[80:h - 10]          # below the bar; white is the background
    for k in range(2):
        panel = drawn[:, k * w // 2 + 10:(k + 1) * w // 2 - 10]
        assert panel.mean() > 0.05, f"panel {k} is (nearly) empty: {panel.mean():.3f} drawn"
    if docs:
        shutil.copyfile(shot, REPO / "docs" / "images" / "view-bunny.png")


def test_a_long_model_is_not_cropped_in_narrow_panels(tmp_path):
    """A box ten times longer than it is wide, in three panels of a 1200×560 window (each
    taller than wide): at the start every panel shows the whole box, a white margin on all
    four sides (the field of view spans the shorter side; before, the box ran off both
    edges of every panel)."""
    import trimesh

    box = trimesh.creation.box(extents=(10, 1, 1)).subdivide()
    mesh = jaxmesh.Mesh.from_arrays(np.asarray(box.vertices, np.float64), np.asarray(box.faces))
    page = tmp_path / "long.html"
    write_viewer(page, [(f"box {k}", mesh) for k in range(3)])
    shot = tmp_path / "shot.png"
    run = _browser(page, f"--screenshot={shot}", "--window-size=1200,560")
    assert run.returncode == 0 and shot.is_file(), run.stderr[-2000:]
    import matplotlib.image

    img = matplotlib.image.imread(str(shot))[..., :3]
    h, w, _ = img.shape
    drawn = np.any(img < 0.9, axis=-1)[80:h - 10]
    for k in range(3):
        panel = drawn[:, k * w // 3 + 4:(k + 1) * w // 3 - 4]
        cols, rows = np.flatnonzero(panel.any(0)), np.flatnonzero(panel.any(1))
        assert cols.size, f"panel {k} is empty"
        assert cols[0] > 0 and cols[-1] < panel.shape[1] - 1, f"panel {k}: the box touches a side, columns {cols[[0, -1]]}"
        assert rows[0] > 0 and rows[-1] < panel.shape[0] - 1, f"panel {k}: the box touches the top or bottom"
        assert cols[-1] - cols[0] > 0.6 * panel.shape[1], f"panel {k}: the box is drawn too small to judge"

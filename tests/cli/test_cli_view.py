"""`jaxmesh view` and the --view pages of denoise, compress and hash: what each page
holds, and the refusals (existing page, --reference without --color-by distance).
The page itself, drawn by a real browser, is tested in tests/test_view.py."""

import jaxmesh
from jaxmesh.cli import main
from conftest import octahedron_arrays, viewer_config


def test_cli_view_and_view_pages_of_other_commands(tmp_path, capsys):
    a = jaxmesh.Mesh.from_arrays(*octahedron_arrays())
    src, ref = tmp_path / "a.ply", tmp_path / "ref.ply"
    jaxmesh.save(jaxmesh.add_noise(a, 0.1, 0), src)
    jaxmesh.save(a, ref)
    page = tmp_path / "v.html"
    assert main(["view", str(src), str(ref), "-o", str(page), "--color-by", "distance", "--reference", str(ref),
                 "--shading", "smooth"]) == 0
    cfg = viewer_config(page.read_text())
    assert [p["label"] for p in cfg["panels"]] == [str(src), str(ref)] and cfg["shading"] == "smooth"
    assert cfg["legend"]["label"] == f"distance to {ref}" and cfg["legend"]["high"] > 0
    assert main(["view", str(src), "-o", str(page)]) == 1
    assert "exists" in capsys.readouterr().err
    assert main(["view", str(src), "-o", str(tmp_path / "new.html"), "--reference", str(ref)]) == 1
    assert "--color-by distance" in capsys.readouterr().err
    # denoise --view: input, result and reference, the first two coloured by the distance to it
    out, dpage = tmp_path / "out.ply", tmp_path / "d.html"
    assert main(["denoise", str(src), str(out), "--method", "taubin", "--iterations", "2", "--reference", str(ref),
                 "--view", str(dpage)]) == 0
    cfg = viewer_config(dpage.read_text())
    assert [("colors" in p) for p in cfg["panels"]] == [True, True, False]
    assert main(["denoise", str(src), str(tmp_path / "o2.ply"), "--method", "taubin", "--view", str(dpage)]) == 1
    assert "exists" in capsys.readouterr().err and not (tmp_path / "o2.ply").exists()   # refused before any work
    # compress --view: the original and the decoded mesh, by vertex error
    cpage = tmp_path / "c.html"
    assert main(["compress", "--sample", "spot", str(tmp_path / "s.jxm"), "--keep", "0.2", "--view", str(cpage)]) == 0
    cfg = viewer_config(cpage.read_text())
    assert len(cfg["panels"]) == 2 and cfg["legend"]["label"] == "vertex error" and cfg["legend"]["high"] > 0
    hpage = tmp_path / "h.html"
    assert main(["hash", "--compare", str(src), str(ref), "--view", str(hpage)]) == 0
    assert len(viewer_config(hpage.read_text())["panels"]) == 2
    assert main(["hash", str(src), "--view", str(hpage)]) == 1

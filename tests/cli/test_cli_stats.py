"""`jaxmesh stats`: the JSON summary equals the library's, the six-panel figure is
written, and an existing figure is never overwritten."""

import json

import pytest

import jaxmesh
from jaxmesh import stats
from jaxmesh.cli import main
from conftest import shared_mesh_path


def test_stats_json_and_figure(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    path = shared_mesh_path("eight.ply")
    s = stats.mesh_statistics(jaxmesh.load(path), sources=20, seed=1)["summary"]
    out = tmp_path / "six.png"
    assert main(["stats", str(path), "--json", "--sources", "20", "--seed", "1", "--plot", str(out)]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["average_degree"] == pytest.approx(s["average_degree"])
    assert printed["geodesic_heat_mean"] == pytest.approx(s["geodesic_heat_mean"])
    assert out.stat().st_size > 10000
    assert main(["stats", str(path), "--plot", str(out)]) == 1
    assert "exists" in capsys.readouterr().err


def test_dense_max_chooses_the_exact_or_the_estimated_spectrum(capsys):
    """Up to ``--dense-max`` vertices the spectra are the dense solver's eigenvalues, above it the
    kernel-polynomial estimate; the summary says which, and a negative size is refused."""
    path = shared_mesh_path("eight.ply")                                   # 766 vertices
    quantiles = {}
    for flag, how in (("766", "exact"), ("765", "estimated (kernel polynomial method)")):
        assert main(["stats", str(path), "--json", "--sources", "4", "--dense-max", flag]) == 0
        printed = json.loads(capsys.readouterr().out)
        assert printed["spectrum"] == how
        quantiles[how] = printed["spectrum_quantiles"]["combinatorial"]
    exact, estimate = quantiles["exact"], quantiles["estimated (kernel polynomial method)"]
    assert exact != estimate and abs(exact[32] - estimate[32]) < 0.05 * (exact[-1] - exact[0])
    with pytest.raises(ValueError, match="dense_max must be a non-negative int, got -1"):
        stats.mesh_statistics(jaxmesh.load(path), sources=4, dense_max=-1)

"""`jaxmesh noise` and `jaxmesh denoise`, on one mesh and on a dataset (--out-dir):
output, exit codes, errors, and files equal to what the library computes."""

import contextlib
import json
import re
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import jaxmesh
from jaxmesh.cli import main
from conftest import shared_mesh_path, tetrahedron_arrays, write_dataset, write_pairs


def test_noise_then_denoise_with_reference(capsys, tmp_path):
    import jaxmesh

    noisy, clean, out = (str(tmp_path / n) for n in ("noisy.ply", "clean.ply", "out.ply"))
    assert main(["noise", "--sample", "spot", noisy, "--sigma", "0.3", "--seed", "1"]) == 0
    assert main(["noise", "--sample", "spot", clean, "--sigma", "0"]) == 0
    np.testing.assert_array_equal(jaxmesh.load(clean).vertices,
                                  jaxmesh.data.load_sample("spot", dtype=np.float64).vertices)
    capsys.readouterr()
    assert main(["denoise", noisy, out, "--method", "kernel", "--lam", "0.5", "--iterations", "4",
                 "--reference", clean, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["params"] == {"lam": 0.5, "iterations": 4, "variant": "random_walk", "safeguard": True}
    assert summary["after"]["visual_error"] < 0.3 * summary["before"]["visual_error"]
    # the file holds what the library computes (in unit-diagonal coordinates and back)
    m = jaxmesh.load(noisy)
    unit, centre, scale = jaxmesh.normalize(m, return_transform=True)
    expect = jaxmesh.denoise.kernel_diffusion(unit, 0.5, 4).vertices * scale + centre[None]
    np.testing.assert_allclose(jaxmesh.load(out).vertices, expect, atol=1e-12)


@pytest.mark.slow   # one compile per method (~25 s in all); the default run denoises with several
def test_every_method_runs_from_the_cli_with_its_defaults(tmp_path, small_pair):
    noisy, _ = small_pair
    for name in jaxmesh.denoise.METHODS:
        assert main(["denoise", noisy, str(tmp_path / f"{name}.ply"), "--method", name]) == 0, name


def test_an_output_that_cannot_be_written_is_refused_before_any_work(capsys, tmp_path, small_pair, monkeypatch):
    """A missing folder, a directory, an unknown mesh suffix, and a .jxm stream under a mesh suffix are
    refused before the input is denoised (the chooser is never called) and nothing is written."""
    import jaxmesh.cli.denoise as cli_denoise

    def never(*args, **kwargs):
        raise AssertionError("the work started before the output was checked")

    monkeypatch.setattr(cli_denoise, "choose_denoiser", never)
    noisy = small_pair[0]
    for out, message in ((tmp_path / "missing" / "o.ply", "does not exist"), (tmp_path, "is a directory"),
                         (tmp_path / "o.xyz", "unsupported mesh format .xyz")):
        assert main(["denoise", noisy, str(out)]) == 1
        assert message in capsys.readouterr().err
        assert main(["noise", noisy, str(out), "--sigma", "0.1"]) == 1
        assert message in capsys.readouterr().err
    assert main(["compress", noisy, str(tmp_path / "c.ply")]) == 1
    assert "names a mesh format" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_denoise_errors(capsys, tmp_path, small_pair):
    noisy, out = small_pair[0], str(tmp_path / "o.ply")
    assert main(["denoise", noisy, out, "--method", "taubin", "--sigma-c", "1"]) == 1
    assert "has no parameter(s) ['sigma_c']" in capsys.readouterr().err
    assert main(["denoise", noisy, out, "--method", "magic"]) == 1
    assert "unknown method 'magic'" in capsys.readouterr().err
    assert main(["denoise", noisy, out, "--method", "kernel", "--lam", "1e-4", "--iterations", "10",
                 "--safeguard", "no"]) == 1
    assert "diverged" in capsys.readouterr().err
    assert not (tmp_path / "o.ply").exists()
    fast = ["--method", "taubin"]                 # the refusals below are the command's, not the method's
    assert main(["denoise", noisy, out, *fast]) == 0
    assert main(["denoise", noisy, out, *fast]) == 1
    assert "exists; use --force" in capsys.readouterr().err
    assert main(["denoise", noisy, out, *fast, "--force", "--reference", str(shared_mesh_path("eight.ply"))]) == 1
    assert "does not have the connectivity" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(["denoise", noisy, out, "--method", "kernel", "--iterations", "2.5"])
    assert e.value.code == 2


@pytest.mark.slow   # blind --lam auto; the default run has test_lam_auto_then_the_reported_lam_writes_the_same_file
def test_denoise_lam_auto_blind(capsys, tmp_path, small_pair):
    noisy, _ = small_pair
    assert main(["denoise", noisy, str(tmp_path / "blind.ply"), "--method", "kernel", "--lam", "auto"]) == 0
    text = capsys.readouterr().out
    assert "tuned lam (blind, noise sigma" in text and "estimated)" in text


@pytest.mark.slow   # the supervised tuner is tested in test_tune; the blind CLI path stays in the default run
@pytest.mark.filterwarnings("ignore:1 isolated vertices:jaxmesh.mesh.MeshWarning")  # small_pair's far vertex
def test_denoise_lam_auto_supervised(capsys, tmp_path, small_pair):
    from jaxmesh.tune import tune

    noisy, clean = small_pair
    out = str(tmp_path / "sup.ply")
    assert main(["denoise", noisy, out, "--method", "kernel", "--lam", "auto", "--reference", clean, "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["tuned"]["mode"] == "supervised" and s["tuned"]["names"] == ["lam"]
    want = tune(jaxmesh.load(noisy), jaxmesh.load(clean))
    assert s["params"]["lam"] == pytest.approx(float(want.params["lam"]), rel=1e-9)
    assert s["after"]["visual_error"] == pytest.approx(float(want.error), rel=1e-9)
    np.testing.assert_allclose(jaxmesh.load(out).vertices, want.mesh.vertices, atol=1e-12)
    # refusals
    assert main(["denoise", noisy, str(tmp_path / "x.ply"), "--method", "bilateral", "--lam", "auto"]) == 1
    assert "has no parameter 'lam'" in capsys.readouterr().err
    assert main(["denoise", noisy, str(tmp_path / "x.ply"), "--method", "kernel", "--lam", "auto", "--raw-units"]) == 1
    assert "drop --raw-units" in capsys.readouterr().err
    assert main(["denoise", noisy, str(tmp_path / "x.ply"), "--method", "kernel", "--lam", "auto",
                 "--noise-sigma", "-1"]) == 1
    assert "--noise-sigma must be > 0" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(["denoise", noisy, str(tmp_path / "x.ply"), "--method", "kernel", "--lam", "often"])
    assert e.value.code == 2


@pytest.mark.slow
def test_denoise_tune_every_continuous_parameter(capsys, tmp_path):
    noisy, clean = str(tmp_path / "noisy.ply"), str(tmp_path / "clean.ply")
    assert main(["noise", "--sample", "spot", noisy, "--sigma", "0.1", "--seed", "2"]) == 0
    assert main(["noise", "--sample", "spot", clean, "--sigma", "0"]) == 0
    capsys.readouterr()
    assert main(["denoise", noisy, str(tmp_path / "t.ply"), "--method", "taubin", "--tune",
                 "--reference", clean, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["tuned"]["names"] == ["lam", "mu"]


@pytest.mark.filterwarnings("ignore:1 isolated vertices:jaxmesh.mesh.MeshWarning")  # small_pair's far vertex
def test_denoise_auto_is_the_default_and_says_what_it_chose(capsys, tmp_path, small_pair, monkeypatch):
    """The CLI's default is the library's choose_denoiser with its defaults (a spy records the
    call: one full search, not two), its report is that result's, and its file is that mesh."""
    import jaxmesh
    import jaxmesh.cli.denoise as cli_denoise
    from jaxmesh.tune import CANDIDATES, choose_denoiser
    from jaxmesh.tune.auto import PATHS
    from jaxmesh.tune.patches import SEARCH_VERTICES

    calls = []

    def spy(*args, **kwargs):
        calls.append((args, kwargs, choose_denoiser(*args, **kwargs)))
        return calls[-1][2]

    monkeypatch.setattr(cli_denoise, "choose_denoiser", spy)
    noisy, clean = small_pair
    out = str(tmp_path / "out.ply")
    assert main(["denoise", noisy, out, "--reference", clean, "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    [(args, kwargs, want)] = calls
    # every other argument at the library's default
    assert kwargs == {"sigma": None, "noise_model": "auto", "search_vertices": SEARCH_VERTICES, "ladder": None}
    np.testing.assert_array_equal(args[0].vertices, jaxmesh.load(noisy).vertices)
    assert s["method"] == want.method and s["params"] == want.params
    assert s["auto"]["improved"] and len(s["auto"]["candidates"]) == len(CANDIDATES) + sum(
        len(p.settings) for p in PATHS)
    stages = s["auto"]["seconds"]
    assert list(stages) == ["noise_law", "patches", "ranking", "choice"] and min(stages.values()) >= 0
    assert sum(stages.values()) <= s["seconds"] + 1e-3 and stages == want.seconds
    assert s["after"]["normal_angle_deg"] < 0.5 * s["before"]["normal_angle_deg"]
    np.testing.assert_allclose(jaxmesh.load(out).vertices, want.mesh.vertices, atol=1e-12)
    assert main(["denoise", noisy, str(tmp_path / "x.ply"), "--lam", "0.3"]) == 1
    assert "--lam needs a named method" in capsys.readouterr().err


@pytest.mark.filterwarnings("ignore:1 isolated vertices:jaxmesh.mesh.MeshWarning")  # small_pair's far vertex
def test_a_negative_error_estimate_is_reported_as_such_not_as_zero():
    """A risk estimate below 0 (a noise level set too high) printed as 0.00° read as a perfect
    result; the report says the estimate is negative instead, and prints degrees otherwise; the JSON
    summary gives null degrees and the signed risk."""
    from types import SimpleNamespace

    from jaxmesh.cli._denoise_report import _estimate

    assert "negative" in _estimate(SimpleNamespace(risk=-0.25, rms_tilt_degrees=0.0)) and "°" not in _estimate(
        SimpleNamespace(risk=-0.25, rms_tilt_degrees=0.0))
    assert _estimate(SimpleNamespace(risk=1e-3, rms_tilt_degrees=1.81)) == "1.81°"
    from jaxmesh.tune import AutoResult

    mesh = jaxmesh.Mesh.from_arrays(*tetrahedron_arrays())
    low, fine = (AutoResult("taubin", {}, mesh, 0.1, True, 0.0, r, 0.04, True, []).summary() for r in (-0.25, 0.01))
    assert low["estimated_rms_normal_error_deg"] is None and low["risk"] == -0.25
    assert fine["estimated_rms_normal_error_deg"] == pytest.approx(np.degrees(0.1)) and fine["noisy_risk"] == 0.04
    assert json.loads(json.dumps(low))["estimated_rms_normal_error_deg"] is None


def test_the_default_writes_a_noise_free_mesh_unchanged(capsys, tmp_path):
    """A mesh whose noise estimate is 0 (a flat grid: an exactly smooth surface) is written unchanged by
    the default command, exit 0, with a warning that says how to denoise it anyway; the library's
    choose_denoiser returns it as method "none"; a given noise level still denoises it."""
    import warnings

    from conftest import grid_arrays
    from jaxmesh.tune import BlindTuningWarning, choose_denoiser

    flat = jaxmesh.Mesh.from_arrays(*grid_arrays(12, 10))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        choice = choose_denoiser(flat)
    assert choice.method == "none" and choice.noise_law == "none" and not choice.improved and choice.table == []
    assert choice.mesh is flat
    blind = [w for w in caught if issubclass(w.category, BlindTuningWarning)]
    assert len(blind) == 1 and "noise-free" in str(blind[0].message)
    src, out = str(tmp_path / "flat.ply"), str(tmp_path / "out.ply")
    jaxmesh.save(flat, src)
    assert main(["denoise", src, out]) == 0
    captured = capsys.readouterr()
    assert "written unchanged" in captured.out and "--noise-sigma" in captured.err
    np.testing.assert_array_equal(jaxmesh.load(out).vertices, flat.vertices)
    assert main(["denoise", src, str(tmp_path / "j.ply"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["method"] == "none" and "noise-free" in summary["warnings"][0]


def test_denoise_auto_passes_the_noise_model_on(capsys, tmp_path, small_pair, monkeypatch):
    """--noise-model reaches the chooser (run here with one candidate and no paths or blends:
    the full search is the test above)."""
    import functools

    import jaxmesh.cli.denoise as cli_denoise
    from jaxmesh.tune import Candidate, choose_denoiser

    small = functools.partial(choose_denoiser, candidates=[Candidate("taubin", {"iterations": 5})], paths=(),
                              blend_draws=0)
    monkeypatch.setattr(cli_denoise, "choose_denoiser", small)
    noisy, _ = small_pair
    assert main(["denoise", noisy, str(tmp_path / "n.ply"), "--noise-model", "normal", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["auto"]["tangential_noise_sigma"] == 0.0
    assert main(["denoise", noisy, str(tmp_path / "i.ply"), "--noise-model", "isotropic"]) == 0
    assert "within the surface (isotropic noise)" in capsys.readouterr().out
    assert main(["denoise", noisy, str(tmp_path / "t.ply"), "--method", "taubin", "--noise-model", "normal"]) == 1
    assert "--noise-model applies to --method auto" in capsys.readouterr().err
    for level in ("1e300", "1e-300"):      # an overflow and a division by zero before the range was checked
        assert main(["denoise", noisy, str(tmp_path / "s.ply"), "--noise-sigma", level]) == 1
        assert "mean edge lengths of this mesh" in capsys.readouterr().err
    assert not (tmp_path / "s.ply").exists()
    with pytest.raises(SystemExit):       # the help states the range the library checks
        main(["denoise", "--help"])
    from jaxmesh.tune import SIGMA_RANGE
    stated = re.search(r"between (\S+) and (\S+) mean edge lengths", " ".join(capsys.readouterr().out.split()))
    assert tuple(map(float, stated.groups())) == SIGMA_RANGE
    assert main(["denoise", noisy, str(tmp_path / "t.ply"), "--method", "taubin", "--search-vertices", "all"]) == 1
    assert "--search-vertices applies to --method auto" in capsys.readouterr().err
    for bad in ("7", "many"):
        with pytest.raises(SystemExit):
            main(["denoise", noisy, str(tmp_path / "b.ply"), "--search-vertices", bad])
        assert "expected an integer >= 32 or 'all'" in capsys.readouterr().err
    assert main(["denoise", noisy, str(tmp_path / "a.ply"), "--search-vertices", "all", "--json"]) == 0
    ranked = json.loads(capsys.readouterr().out)["auto"]
    assert ranked["search_vertices"] > 0 and ranked["draws"] == 2
    assert main(["denoise", noisy, str(tmp_path / "f.ply"), "--noise-model", "impulsive", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["auto"]["noise_law"] == "impulsive" and s["auto"]["tangential_noise_sigma"] == 0.0


@pytest.mark.filterwarnings("ignore:1 isolated vertices:jaxmesh.mesh.MeshWarning")  # small_pair's far vertex
def test_the_search_ladder_reaches_the_chooser_and_makes_the_same_choice(capsys, tmp_path, small_pair, monkeypatch):
    """--search-ladder R pads the search (a small one here) and writes the file the unpadded search
    writes; with --out-dir it reaches every mesh's chooser; a bad ratio, a named method or another
    parameter beside it are refused with the flag named."""
    import functools

    import jaxmesh.cli.denoise as cli_denoise
    import jaxmesh.tune as tune
    from jaxmesh.tune import Candidate, choose_denoiser

    seen = []

    def small(*args, **kw):
        seen.append(kw.get("ladder"))
        return choose_denoiser(*args, candidates=[Candidate("guided_normal", {"sigma_r": 0.3})],
                               paths=(tune.PATHS[0],), blend_draws=0, **kw)
    monkeypatch.setattr(cli_denoise, "choose_denoiser", small)
    monkeypatch.setattr(tune, "choose_denoiser", small)          # the dataset runner's
    noisy, _ = small_pair
    assert main(["denoise", noisy, str(tmp_path / "p.ply"), "--search-ladder", "1.19", "--json"]) == 0
    padded = json.loads(capsys.readouterr().out)
    assert main(["denoise", noisy, str(tmp_path / "u.ply"), "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert seen == [1.19, None] and padded["auto"]["candidates"][0]["params"] == plain["auto"]["candidates"][0]["params"]
    np.testing.assert_allclose(jaxmesh.load(tmp_path / "p.ply").vertices, jaxmesh.load(tmp_path / "u.ply").vertices,
                               atol=1e-6)
    assert main(["denoise", noisy, "--out-dir", str(tmp_path / "d"), "--search-ladder", "1.19"]) == 0
    assert seen[-1] == 1.19 and (tmp_path / "d" / Path(noisy).name).exists()
    capsys.readouterr()
    for argv, message in ((["--search-ladder", "1"], "expected a number > 1"),
                          (["--search-ladder", "inf"], "expected a number > 1"),
                          (["--method", "taubin", "--search-ladder", "1.2"], "--search-ladder applies to --method auto")):
        with pytest.raises(SystemExit) if "expected" in message else contextlib.nullcontext():
            assert main(["denoise", noisy, str(tmp_path / "b.ply"), *argv]) == 1
        assert message in capsys.readouterr().err
    assert main(["denoise", noisy, "--out-dir", str(tmp_path / "e"), "--search-ladder", "1.2", "--lam", "0.3"]) == 1
    assert "chooses its own parameters" in capsys.readouterr().err


def test_denoise_auto_says_when_it_ranked_on_patches(capsys, tmp_path, monkeypatch):
    """Above the patch threshold the report says on how many vertices the candidates were ranked and the
    JSON summary carries it; --search-vertices all ranks on the whole mesh (one candidate here: the
    full search is the default test's)."""
    import functools

    import trimesh

    import jaxmesh.cli.denoise as cli_denoise
    from jaxmesh.tune import Candidate, choose_denoiser

    small = functools.partial(choose_denoiser, candidates=[Candidate("taubin", {"iterations": 5})], paths=(),
                              blend_draws=0)
    monkeypatch.setattr(cli_denoise, "choose_denoiser", small)
    ball = trimesh.creation.icosphere(4)                       # 2562 vertices > 6 x 64
    clean = str(tmp_path / "ball.ply")
    jaxmesh.save(jaxmesh.Mesh.from_arrays(ball.vertices, ball.faces), clean)
    noisy = str(tmp_path / "noisy.ply")
    assert main(["noise", clean, noisy, "--sigma", "0.2"]) == 0
    capsys.readouterr()
    assert main(["denoise", noisy, str(tmp_path / "p.ply"), "--search-vertices", "64"]) == 0
    assert "ranked on patches of " in capsys.readouterr().out
    assert main(["denoise", noisy, str(tmp_path / "w.ply"), "--search-vertices", "all", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["auto"]["search_vertices"] == 2562


@pytest.mark.slow   # a whole impulsive search from the command line (~9 s); the library path runs by default
def test_denoise_auto_reads_impulsive_noise_and_says_so(capsys, tmp_path, monkeypatch):
    """A mesh made with `jaxmesh noise --model impulsive` is read as impulsive by the default
    command, which reports the fraction it read and ranks the robust candidates too."""
    import functools

    import jaxmesh.cli.denoise as cli_denoise
    from jaxmesh.tune import Candidate, choose_denoiser

    small = functools.partial(choose_denoiser, candidates=[Candidate("taubin", {"iterations": 5})], paths=(),
                              impulsive_candidates=[Candidate("impulse_repair", {"iterations": 1})], blend_draws=0)
    monkeypatch.setattr(cli_denoise, "choose_denoiser", small)
    import trimesh

    ball = trimesh.creation.icosphere(4)                       # 2562 vertices: the decision needs 500
    clean = str(tmp_path / "ball.ply")
    jaxmesh.save(jaxmesh.Mesh.from_arrays(ball.vertices, ball.faces), clean)
    spiky = str(tmp_path / "spiky.ply")
    assert main(["noise", clean, spiky, "--model", "impulsive", "--sigma", "0.5", "--fraction", "0.5"]) == 0
    capsys.readouterr()
    assert main(["denoise", spiky, str(tmp_path / "d.ply"), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["auto"]["noise_law"] == "impulsive" and 0.4 < s["auto"]["noise_fraction"] < 0.6
    assert {c["method"] for c in s["auto"]["candidates"]} == {"taubin", "impulse_repair"}
    assert main(["denoise", spiky, str(tmp_path / "e.ply")]) == 0
    assert "impulsive noise:" in capsys.readouterr().out


@pytest.mark.filterwarnings("ignore:1 isolated vertices:jaxmesh.mesh.MeshWarning")  # small_pair's far vertex
def test_lam_auto_then_the_reported_lam_writes_the_same_file(capsys, tmp_path, small_pair):
    """One frame for the CLI and the tuner: on a mesh with an isolated vertex far
    away (where the bounding boxes of all and of used vertices differ), --lam auto
    and --lam <the λ it reports> run the same computation, bit for bit."""
    src, clean = small_pair
    assert main(["denoise", src, str(tmp_path / "a.ply"), "--method", "kernel", "--lam", "auto",
                 "--reference", clean]) == 0
    line = capsys.readouterr().out.splitlines()[0]
    lam = line.split("lam=")[1].split()[0]  # printed as repr: every digit
    assert main(["denoise", src, str(tmp_path / "b.ply"), "--method", "kernel", "--lam", lam]) == 0
    assert (tmp_path / "a.ply").read_bytes() == (tmp_path / "b.ply").read_bytes()
    # and the isolated vertex stays where it was
    out = jaxmesh.load(tmp_path / "a.ply", dtype=np.float64)
    np.testing.assert_allclose(np.asarray(out.vertices)[-1], [5.0, 5.0, 5.0], atol=1e-12)


# --------------------------------------------------------------------------- datasets (--out-dir)
@pytest.mark.filterwarnings("ignore::jaxmesh.mesh.MeshWarning")
def test_a_corrupt_file_is_reported_and_skipped_and_the_exit_status_says_so(tmp_path, capsys):
    paths = write_dataset(tmp_path / "in", 4)
    (tmp_path / "in" / "m1b.ply").write_text("ply\nformat ascii 1.0\nelement vertex 9\nend_header\n0 0\n")
    (tmp_path / "in" / "notes.txt").write_text("not a mesh, not picked up")
    whole = paths[2].read_bytes()                       # its header is intact, its body cut: fails when read
    (tmp_path / "in" / "m2b.ply").write_bytes(whole[: len(whole) - 40])
    report = tmp_path / "r.jsonl"
    rc = main(["denoise", "--out-dir", str(tmp_path / "out"), str(tmp_path / "in"), "--method", "taubin",
               "--report", str(report)])
    out, err = capsys.readouterr()
    assert rc == 1 and "4 written, 0 skipped (exist), 2 failed" in out
    assert err.count("jaxmesh: error:") == 2 and "m1b.ply" in err and "m2b.ply" in err
    lines = [json.loads(line) for line in report.read_text().splitlines()]
    assert sorted(r["status"] for r in lines) == ["failed"] * 2 + ["ok"] * 4
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(p.name for p in paths)


def test_out_dir_refuses_what_it_cannot_do(tmp_path, capsys):
    for flags, message in ((["--method", "kernel", "--raw-units"], "not supported with --out-dir"),
                           (["--noise-model", "normal"], "--noise-model: not supported with --out-dir"),
                           (["--method", "kernel", "--tune-on", "2"], "--tune-on N tunes the parameters given"),
                           (["--tune"], "--tune needs a named method"),
                           (["--method", "cauchy_diffusion", "--pack"],
                            "cannot pack the meshes (pack=True, --pack): cauchy_diffusion"),
                           (["--method", "taubin", "--pack", "--batch-size", "2"], "not both")):
        assert main(["denoise", "--out-dir", str(tmp_path / "o"), str(tmp_path)] + flags) == 1
        assert message in capsys.readouterr().err, flags
    assert not (tmp_path / "o").exists()


def test_out_dir_with_references_and_one_setting_tuned_on_a_subset(tmp_path, capsys):
    """--reference DIR: errors per mesh in the report and their means on stdout;
    --tune-on 1: λ tuned once, against the first input's reference, for all."""
    names = write_pairs(tmp_path, 2)
    report = tmp_path / "r.jsonl"
    rc = main(["denoise", "--out-dir", str(tmp_path / "out"), str(tmp_path / "in"), "--method", "kernel",
               "--iterations", "2", "--lam", "auto", "--tune-on", "1", "--reference", str(tmp_path / "clean"),
               "--report", str(report)])
    out = capsys.readouterr().out
    lines = sorted((json.loads(line) for line in report.read_text().splitlines()), key=lambda r: r["input"])
    assert rc == 0 and [r["status"] for r in lines] == ["ok", "ok"]
    lam = lines[0]["params"]["lam"]
    assert lines[1]["params"]["lam"] == lam and lines[0]["tuned_on"]["files"] == [str(tmp_path / "in" / names[0])]
    assert f"tuned on 1 inputs (supervised): iterations = 2, lam = {lam:.6g}\n" in out
    before = np.mean([r["before"]["normal_angle_deg"] for r in lines])
    after = np.mean([r["after"]["normal_angle_deg"] for r in lines])
    ratio = np.exp(np.mean([np.log(r["after"]["visual_error"] / r["before"]["visual_error"]) for r in lines]))
    assert after < before and ratio < 1
    assert f"(2 meshes): mean normal error {before:.2f}° -> {after:.2f}°; visual error after / before {ratio:.3g}" in out


@pytest.mark.slow   # compiles the blind shared tuner
@pytest.mark.filterwarnings("ignore::jaxmesh.tune.BlindTuningWarning")
def test_out_dir_tune_every_parameter_blind_on_a_subset(tmp_path, capsys):
    write_pairs(tmp_path, 2)
    rc = main(["denoise", "--out-dir", str(tmp_path / "out"), str(tmp_path / "in"), "--method", "kernel",
               "--iterations", "2", "--tune", "--tune-on", "2", "--json"])
    s = json.loads(capsys.readouterr().out)
    assert rc == 0 and s["done"] == 2 and "mean_errors" not in s
    assert s["tuned_on"]["supervised"] is False and len(s["tuned_on"]["files"]) == 2
    assert 0 < s["tuned_on"]["params"]["lam"] and s["tuned_on"]["params"]["iterations"] == 2


@pytest.mark.slow   # three subprocesses, each importing JAX and compiling
@pytest.mark.filterwarnings("ignore::jaxmesh.mesh.MeshWarning")
def test_two_processes_with_jax_distributed_equal_one(tmp_path):
    """Two CLI processes on 127.0.0.1 (jax.distributed, a free coordinator port),
    each denoising its share: together they write exactly the files one process
    writes, byte for byte."""
    write_dataset(tmp_path / "in", 6)
    common = [sys.executable, "-m", "jaxmesh", "denoise", str(tmp_path / "in"), "--method", "taubin",
              "--iterations", "4", "--batch-size", "2"]
    assert subprocess.run(common + ["--out-dir", str(tmp_path / "one")], capture_output=True).returncode == 0
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    procs = [subprocess.Popen(common + ["--out-dir", str(tmp_path / "two"), "--coordinator", f"127.0.0.1:{port}",
                                        "--num-processes", "2", "--process-id", str(i)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE) for i in (0, 1)]
    outs = [p.communicate(timeout=120) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [o[1][-500:] for o in outs]
    written = [int(o[0].split()[0]) for o in outs]
    assert sorted(written) == [3, 3]                                  # each its share
    one = sorted(p.name for p in (tmp_path / "one").iterdir())
    assert sorted(p.name for p in (tmp_path / "two").iterdir()) == one
    for name in one:
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "two" / name).read_bytes()




def test_noise_impulsive_model(capsys, tmp_path):
    import jaxmesh

    out = str(tmp_path / "imp.ply")
    assert main(["noise", "--sample", "spot", out, "--sigma", "0.5", "--model", "impulsive", "--fraction", "0.3",
                 "--seed", "2"]) == 0
    assert "impulsive noise (fraction 0.3) sigma=0.5" in capsys.readouterr().err
    spot = jaxmesh.data.load_sample("spot", dtype=np.float64)
    expect = jaxmesh.add_impulsive_noise(spot, 0.5, 2, fraction=0.3)
    np.testing.assert_allclose(jaxmesh.load(out).vertices, expect.vertices, rtol=0, atol=1e-12)
    bad = str(tmp_path / "bad.ply")
    assert main(["noise", "--sample", "spot", bad, "--model", "impulsive", "--fraction", "1.5"]) == 1
    assert "--fraction must be in [0, 1]" in capsys.readouterr().err
    assert main(["noise", "--sample", "spot", bad, "--fraction", "0.5"]) == 1
    assert "--fraction applies to --model impulsive only" in capsys.readouterr().err
    assert main(["noise", "--sample", "spot", bad, "--sigma", "inf"]) == 1
    assert not (tmp_path / "bad.ply").exists()


def test_the_progress_bar_is_for_large_meshes_at_a_terminal(monkeypatch):
    """`jaxmesh denoise`'s bar hooks the loop (which then compiles anew) only at a terminal and
    for a mesh of BAR_VERTICES or more; elsewhere no hook, so the run uses the kept program."""
    from jaxmesh.cli._denoise_report import BAR_VERTICES, progress_bar
    from jaxmesh.denoise._loop import reporting

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    with progress_bar("kernel", 5, BAR_VERTICES - 1):
        assert not reporting()
    with progress_bar("kernel", 5, BAR_VERTICES):
        assert reporting()
    assert not reporting()
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    with progress_bar("kernel", 5, BAR_VERTICES):
        assert not reporting()

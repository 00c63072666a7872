"""The jaxmesh command line: output, exit codes, errors."""

import json
import subprocess
import sys

import numpy as np
import pytest

import jaxmesh
from jaxmesh.cli import main
from conftest import shared_mesh_path


@pytest.fixture(scope="module")
def small_pair(tmp_path_factory):
    """A noisy icosphere (642 vertices, σ = 0.3 ℓ̄) with one isolated vertex far away
    (so the boxes of all and of used vertices differ), and its clean original, as
    files.  The commands' logic does not need the 2.9k-vertex sample; the tests that
    tune share one compiled tuner through these shapes."""
    import trimesh

    d = tmp_path_factory.mktemp("small")
    s = trimesh.creation.icosphere(3)
    clean = jaxmesh.Mesh.from_arrays(np.vstack([s.vertices, [[5.0, 5.0, 5.0]]]), s.faces, warn=False)
    noisy = jaxmesh.add_noise(clean, 0.3, 7)
    noisy = noisy.with_vertices(noisy.vertices.at[-1].set(clean.vertices[-1]))
    paths = str(d / "noisy.ply"), str(d / "clean.ply")
    jaxmesh.save(noisy, paths[0])
    jaxmesh.save(clean, paths[1])
    return paths


def test_info_json_on_sample(capsys):
    assert main(["info", "--json", "--sample", "spot"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["vertices"], info["faces"], info["edges"], info["euler_characteristic"]) == (2930, 5856, 8784, 2)
    assert info["genus"] == 0 and info["path"] == "sample:spot"


def test_info_human_output_and_several_files(capsys, tmp_path):
    p = shared_mesh_path("eight.ply")
    assert main(["info", str(p), str(p)]) == 0
    out = capsys.readouterr().out
    assert out.count("eight.ply") == 2 and "genus" in out and "euler characteristic   -2" in out
    assert main(["info", "--json", str(p), str(p)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert [json.loads(ln)["genus"] for ln in lines] == [2, 2]


def test_errors_and_exit_codes(capsys, tmp_path):
    assert main(["info"]) == 1
    assert "no mesh given" in capsys.readouterr().err
    assert main(["info", str(tmp_path / "absent.ply")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("jaxmesh: error:") and "no such file" in err
    bad = tmp_path / "bad.off"
    bad.write_text("nonsense")
    assert main(["info", str(bad)]) == 1
    assert "bad.off" in capsys.readouterr().err
    assert main([]) == 2
    with pytest.raises(SystemExit) as e:
        main(["info", "--sample", "nope"])
    assert e.value.code == 2


def test_warnings_go_to_stderr(capsys, tmp_path):
    q = tmp_path / "quad.obj"
    q.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    assert main(["info", "--json", str(q)]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["faces"] == 2
    assert "jaxmesh: warning:" in captured.err and "polygons" in captured.err


def test_python_dash_m_entry_point():
    r = subprocess.run([sys.executable, "-m", "jaxmesh", "info", "--json", "--sample", "spot"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["vertices"] == 2930


def test_convert_never_overwrites_without_force(capsys, tmp_path):
    import jaxmesh

    src = shared_mesh_path("eight.ply")
    out = tmp_path / "eight.obj"
    assert main(["convert", str(src), str(out)]) == 0
    assert jaxmesh.load(out).num_faces == 1536
    out.write_text("keep me")
    assert main(["convert", str(src), str(out)]) == 1
    assert "--force" in capsys.readouterr().err and out.read_text() == "keep me"
    assert main(["convert", str(src), str(out), "--force"]) == 0
    assert jaxmesh.load(out).num_faces == 1536
    # PLY -> PLY keeps every coordinate bit
    ply = tmp_path / "eight.ply"
    assert main(["convert", str(src), str(ply)]) == 0
    import trimesh

    np.testing.assert_array_equal(trimesh.load(ply, process=False).vertices,
                                  trimesh.load(src, process=False).vertices)


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
    assert main(["denoise", noisy, out]) == 0
    assert main(["denoise", noisy, out]) == 1
    assert "exists; use --force" in capsys.readouterr().err
    assert main(["denoise", noisy, out, "--force", "--reference", str(shared_mesh_path("eight.ply"))]) == 1
    assert "does not have the connectivity" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(["denoise", noisy, out, "--method", "kernel", "--iterations", "2.5"])
    assert e.value.code == 2


def test_list_methods_and_demo(capsys, tmp_path):
    from jaxmesh.denoise import METHODS

    assert main(["denoise", "--list-methods"]) == 0
    listing = capsys.readouterr().out
    assert all(f"{name}:" in listing for name in METHODS)
    assert main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    rows = {ln.split()[0]: ln for ln in out.splitlines() if ln.startswith(("noisy", "kernel", "taubin"))}
    ratio = lambda ln: float(ln.split("x")[0].split()[-1])  # noqa: E731
    assert ratio(rows["noisy"]) == 1.0 and ratio(rows["kernel"]) < 0.2 and ratio(rows["taubin"]) < 0.2
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "bunny_clean.ply", "bunny_kernel.ply", "bunny_noisy.ply", "bunny_taubin.ply"]
    assert main(["demo", "--out", str(tmp_path)]) == 1
    assert main(["demo", "--out", str(tmp_path), "--force"]) == 0


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
def test_denoise_auto_is_the_default_and_says_what_it_chose(capsys, tmp_path, small_pair):
    import jaxmesh
    from jaxmesh.tune import CANDIDATES, choose_denoiser
    from jaxmesh.tune.auto import TAUBIN_LAMS, TAUBIN_PASS_BANDS

    noisy, clean = small_pair
    out = str(tmp_path / "out.ply")
    assert main(["denoise", noisy, out, "--reference", clean, "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    want = choose_denoiser(jaxmesh.load(noisy))
    assert s["method"] == want.method and s["params"] == want.params
    assert s["auto"]["improved"] and len(s["auto"]["candidates"]) == len(CANDIDATES) + len(TAUBIN_LAMS) * len(
        TAUBIN_PASS_BANDS)
    assert s["after"]["normal_angle_deg"] < 0.5 * s["before"]["normal_angle_deg"]
    np.testing.assert_allclose(jaxmesh.load(out).vertices, want.mesh.vertices, atol=1e-12)
    assert main(["denoise", noisy, str(tmp_path / "x.ply"), "--lam", "0.3"]) == 1
    assert "--lam needs a named method" in capsys.readouterr().err


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

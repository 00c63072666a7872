"""The command line as a Unix tool: `jaxmesh info`, `convert`, `demo`, `--list-methods`,
`python -m jaxmesh`; exit codes, errors and warnings on stderr, files never overwritten
unless asked.  Every command's own tests are beside this file (tests/cli/)."""

import json
import subprocess
import sys

import numpy as np
import pytest

from jaxmesh.cli import main
from conftest import shared_mesh_path


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


def test_the_executable_flushes_everything_and_keeps_every_exit_status(tmp_path):
    """``python -m jaxmesh`` (the executable) exits without the interpreter's teardown: what it printed
    and wrote is all there, and the exit statuses are main's and argparse's."""
    def run(*args):
        return subprocess.run([sys.executable, "-m", "jaxmesh", *args], capture_output=True, text=True, timeout=120)

    out = tmp_path / "n.ply"
    written = run("noise", "--sample", "spot", str(out), "--sigma", "0.1")
    assert written.returncode == 0 and "jaxmesh: wrote" in written.stderr, written.stderr
    import jaxmesh

    assert jaxmesh.load(out).num_vertices == 2930                 # the file is complete
    both = run("info", "--json", str(out), str(tmp_path / "missing.ply"))
    assert both.returncode == 1 and "missing.ply" in both.stderr
    assert json.loads(both.stdout.splitlines()[0])["vertices"] == 2930   # printed before the error, flushed
    usage = run("denoise", "--no-such-flag")
    assert usage.returncode == 2 and "usage:" in usage.stderr
    helped = run("--help")
    from jaxmesh.cli import COMMANDS

    assert helped.returncode == 0 and all(name in helped.stdout for name in COMMANDS)   # the whole help


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


def test_list_methods_and_demo(capsys, tmp_path):
    from jaxmesh.denoise import METHODS

    assert main(["denoise", "--list-methods"]) == 0
    listing = capsys.readouterr().out
    assert all(f"{name}:" in listing for name in METHODS)
    heads = {ln.split(":")[0]: ln for ln in listing.splitlines() if not ln.startswith(" ")}
    assert all(("(packed into disjoint unions" in heads[name]) == m.packable for name, m in METHODS.items())
    assert main(["demo", "--out", str(tmp_path), "--no-auto"]) == 0        # the blind default: the slow test
    out = capsys.readouterr().out
    rows = {ln.split()[0]: ln for ln in out.splitlines() if ln.startswith(("noisy", "kernel", "taubin"))}
    ratio = lambda ln: float(ln.split("x")[0].split()[-1])  # noqa: E731
    assert ratio(rows["noisy"]) == 1.0 and ratio(rows["kernel"]) < 0.2 and ratio(rows["taubin"]) < 0.2
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "bunny_clean.ply", "bunny_kernel.ply", "bunny_noisy.ply", "bunny_taubin.ply"]
    assert main(["demo", "--out", str(tmp_path), "--no-auto"]) == 1
    assert main(["demo", "--out", str(tmp_path), "--no-auto", "--force"]) == 0
    # the folder is made when missing (the README's first command runs `jaxmesh demo` in a fresh checkout)
    fresh = tmp_path / "new" / "jaxmesh-demo"
    assert main(["demo", "--out", str(fresh), "--no-auto"]) == 0
    assert sorted(p.name for p in fresh.iterdir()) == [
        "bunny_clean.ply", "bunny_kernel.ply", "bunny_noisy.ply", "bunny_taubin.ply"]
    capsys.readouterr()
    assert main(["demo", "--out", str(fresh / "bunny_clean.ply"), "--no-auto"]) == 1
    assert "exists and is not a directory" in capsys.readouterr().err


@pytest.mark.slow   # the blind search on the 35k-vertex bunny
def test_the_demo_shows_the_blind_default_beside_the_filters(capsys, tmp_path):
    assert main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    rows = {ln.split()[0].rstrip(","): ln for ln in out.splitlines() if ln.startswith(("noisy", "taubin", "auto"))}
    normal = lambda ln: float(ln.split("°")[0].split()[-1])  # noqa: E731
    assert normal(rows["auto"]) < normal(rows["taubin"]) < normal(rows["noisy"])
    assert (tmp_path / "bunny_auto.ply").is_file()


def test_a_dangling_symlink_output_is_named_as_such(tmp_path, capsys):
    link = tmp_path / "out.ply"
    link.symlink_to(tmp_path / "missing" / "x.ply")
    assert main(["noise", "--sample", "spot", str(link), "--sigma", "0.1"]) == 1
    assert "is a symbolic link to" in capsys.readouterr().err
    assert main(["noise", "--sample", "spot", str(link), "--sigma", "0.1", "--force"]) == 0
    assert not link.is_symlink() and link.is_file()

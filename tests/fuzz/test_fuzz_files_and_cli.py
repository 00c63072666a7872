"""Untrusted mesh files and hostile CLI use: the fuzz suites (fast part by default,
long part under -m slow) and one test per defect class an audit of files and the CLI found."""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time
import warnings

import jax.numpy as jnp
import numpy as np
import pytest

import harness
import jaxmesh
from jaxmesh import MeshFileError
from jaxmesh.cli import main
from jaxmesh.denoise import METHODS, Method

from conftest import tetrahedron_arrays

# a shell's background jobs ignore SIGINT and children inherit that: reset it, then exec
# (a preexec_fn would fork a multithreaded JAX process)
WITH_SIGINT = [sys.executable, "-c", "import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); "
               "os.execv(sys.executable, [sys.executable, *sys.argv[1:]])"]


def _no_bad(results):
    assert not harness.bad(results), harness.bad(results)[:5]
    return harness.summary(results)


# --------------------------------------------------------------------------- the suites
def test_fuzz_mesh_files_fast():
    counts = _no_bad(harness.run("meshfile", range(150), timeout_s=20, mem_mb=500))
    assert counts["error"] >= 50 and counts["valid"] >= 50


@pytest.mark.slow
def test_fuzz_mesh_files_1500():
    res = harness.run("meshfile", range(1500), timeout_s=20, mem_mb=500)
    counts = _no_bad(res)
    print(counts, "controls (unchanged):", sum("(unchanged)" in r["label"] for r in res))


def test_fuzz_cli_fast():
    # the cheapest commands on every tiny and dirty mesh (info, info --json); convert, noise,
    # stats and every other command run with -m slow
    import cli

    _no_bad(harness.run("cli", range(len(cli.MESHES) * 2), timeout_s=120, mem_mb=3000))


@pytest.mark.slow
def test_fuzz_cli_every_command_and_method():
    import cli

    n = len(cli.MESHES) * len(cli._commands())
    print(_no_bad(harness.run("cli", range(n), timeout_s=300, mem_mb=3000)))


# --------------------------------------------------------------------------- text formats
def test_off_and_obj_keep_every_digit_of_a_nanometre_mesh(tmp_path):
    v, f = tetrahedron_arrays()
    v = (v + np.random.default_rng(0).random(v.shape)) * 1e-9
    mesh = jaxmesh.Mesh.from_arrays(v, f)
    for fmt in ("off", "obj"):
        back = jaxmesh.load(jaxmesh.save(mesh, tmp_path / f"t.{fmt}"), dtype=np.float64)
        np.testing.assert_array_equal(np.asarray(back.vertices), v)  # before: 10 absolute decimals


@pytest.mark.parametrize("fmt,content", [
    ("obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 1"),   # cut mid-number
    ("off", "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3"),
    ("off", "OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n"),                       # a face missing
])
def test_truncated_text_files_are_refused(tmp_path, fmt, content):
    p = tmp_path / f"t.{fmt}"
    p.write_text(content)
    with pytest.raises(MeshFileError, match="truncated"):
        jaxmesh.load(p)


@pytest.mark.parametrize("prefix,comment", [
    (b"\xef\xbb\xbf", b""),                                 # a UTF-8 byte-order mark before the first v
    (b"", "# café\n".encode("latin-1")),                    # a Latin-1 comment (no charset_normalizer)
    (b"", "# café ☃\n".encode()),
])
def test_bom_and_encodings_read_the_same_mesh(tmp_path, prefix, comment):
    body = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    p = tmp_path / "t.obj"
    p.write_bytes(prefix + comment + body)
    m = jaxmesh.load(p, dtype=np.float64)
    assert m.num_vertices == 4 and m.num_faces == 4
    np.testing.assert_array_equal(np.asarray(m.faces)[0], [0, 2, 1])


def test_an_unknown_obj_statement_is_an_error_not_a_dropped_vertex(tmp_path):
    p = tmp_path / "t.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nw 0 1 0\nv 0 0 1\nv 1 1 1\nf 1 2 3\n")
    with pytest.raises(MeshFileError, match="line 3: unknown OBJ statement 'w'"):
        jaxmesh.load(p)


def test_coordinates_beyond_float32_are_an_error_not_inf():
    v, f = tetrahedron_arrays()
    with pytest.raises(ValueError, match="does not fit in float32"):
        jaxmesh.Mesh.from_arrays(v * 1e39, f, dtype=jnp.float32)
    assert jaxmesh.Mesh.from_arrays(v * 1e39, f, dtype=jnp.float64).dtype == jnp.float64


def test_ply_header_counts_are_checked_before_reading(tmp_path):
    p = tmp_path / "t.ply"
    jaxmesh.save(jaxmesh.Mesh.from_arrays(*tetrahedron_arrays()), p)
    data = p.read_bytes().replace(b"element vertex 4", b"element vertex 1000000000000")
    p.write_bytes(data)
    with pytest.raises(MeshFileError, match="need at least 24000000000004 bytes"):
        jaxmesh.load(p)


# --------------------------------------------------------------------------- parameters
@pytest.mark.parametrize("method,params,match", [
    ("kernel", {"lam": -1.0}, r"lam must be a finite number in \(0, 1e\+06\]"),
    ("kernel", {"lam": 0.0}, "lam must be"),
    ("kernel", {"lam": float("nan")}, "lam must be"),
    ("kernel", {"lam": float("inf")}, "lam must be"),
    ("kernel", {"lam": 1e30}, "lam must be"),
    ("taubin", {"mu": 0.5}, r"mu must be a finite number in \[-1, 0\)"),
    ("guided_normal", {"sigma_r": -0.1}, "sigma_r must be"),
    ("hc", {"alpha": 2.0}, "alpha must be"),
])
def test_out_of_domain_parameters_are_refused(tetra, method, params, match):
    with pytest.raises(ValueError, match=match):
        METHODS[method](tetra, **params)


def test_taubin_without_a_pass_band_is_a_warning(tetra):
    """μ > −λ: not Taubin's low-pass filter (the tuner may still find it best)."""
    from jaxmesh import MeshWarning

    with pytest.warns(MeshWarning, match="not a low-pass filter"):
        METHODS["taubin"](tetra, lam=0.6, mu=-0.5)


def test_the_domain_is_not_checked_on_traced_values(tetra):
    import jax

    out = jax.jit(lambda lam: METHODS["kernel"](tetra, lam=lam).vertices)(0.3)
    assert np.isfinite(np.asarray(out)).all()


def test_a_non_finite_result_is_an_error_not_a_nan_mesh(tetra):
    broken = Method("broken", lambda mesh, step: mesh.with_vertices(mesh.vertices * jnp.nan),
                    {"step": METHODS["umbrella_flow"].params["lam"]}, "returns NaN", "-")
    with pytest.raises(FloatingPointError, match="broken produced non-finite coordinates"):
        broken(tetra)


def test_stats_knn_is_validated_and_clamped_on_small_meshes(tetra):
    from jaxmesh.stats import mesh_statistics

    with pytest.raises(ValueError, match="knn must be a positive int"):
        mesh_statistics(tetra, sources=2, knn=0)
    st = mesh_statistics(tetra, sources=2)  # knn 8 on 4 vertices: all 3 others
    assert st["summary"]["vertices"] == 4


# --------------------------------------------------------------------------- CLI errors
def _cli(capsys, *argv):
    code = main(list(map(str, argv)))
    err = capsys.readouterr().err.strip().splitlines()
    return code, [ln for ln in err if not ln.startswith("jaxmesh: warning")]


def test_os_errors_are_one_line(tmp_path, capsys, monkeypatch):
    src = tmp_path / "t.ply"
    jaxmesh.save(jaxmesh.Mesh.from_arrays(*tetrahedron_arrays()), src)

    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    code, err = _cli(capsys, "convert", src, tmp_path / "out.off")
    assert code == 1 and err == ["jaxmesh: error: No space left on device"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.ply"]  # no output, no temporary file


def test_a_directory_is_named_as_such(tmp_path, capsys):
    d = tmp_path / "dir.ply"
    d.mkdir()
    code, err = _cli(capsys, "info", d)
    assert code == 1 and err == [f"jaxmesh: error: {d}: is a directory, not a mesh file"]
    src = tmp_path / "t.ply"
    jaxmesh.save(jaxmesh.Mesh.from_arrays(*tetrahedron_arrays()), src)
    code, err = _cli(capsys, "convert", src, d, "--force")
    assert code == 1 and err == [f"jaxmesh: error: {d}: is a directory; refusing to replace it with a file"]


def test_memory_error_is_one_line(tmp_path, capsys, monkeypatch):
    import jaxmesh.cli.info

    src = tmp_path / "t.ply"
    jaxmesh.save(jaxmesh.Mesh.from_arrays(*tetrahedron_arrays()), src)

    def boom(*a, **k):
        raise MemoryError()

    monkeypatch.setattr(jaxmesh.cli.info, "mesh_info", boom)
    code, err = _cli(capsys, "info", src)
    assert code == 1 and len(err) == 1 and err[0].startswith("jaxmesh: error: out of memory")


def test_blind_tuning_says_when_it_cannot_vouch(capsys, tmp_path):
    """Cow-like case: a clean mesh, so σ̂ reads the surface's own detail."""
    from jaxmesh.tune import PATHS, BlindTuningWarning, SearchPath, choose_denoiser

    clean = jaxmesh.data.load_sample("spot", dtype="float64")
    # the caveat reads σ̂ alone, so one short Taubin path is search enough; its setting (λ = 0.2,
    # k_PB = 0.1) finds a count estimated to help, so the σ̂ caveat is the only one
    path = SearchPath("taubin", PATHS[0].settings[2:3], (), 5)
    with pytest.warns(BlindTuningWarning, match="below 0.1"):
        assert choose_denoiser(clean, candidates=(), paths=(path,), draws=1, blend_draws=0).improved


# --------------------------------------------------------------------------- files
def test_written_files_follow_the_umask(tmp_path):
    old = os.umask(0o027)
    try:
        p = jaxmesh.save(jaxmesh.Mesh.from_arrays(*tetrahedron_arrays()), tmp_path / "t.ply")
    finally:
        os.umask(old)
    assert (p.stat().st_mode & 0o777) == 0o640  # mkstemp alone gives 0600


def test_stale_temporary_files_of_dead_writers_are_removed(tmp_path):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".t.ply.{dead.pid}.abc123.tmp"
    live = tmp_path / f".t.ply.{os.getppid()}.def456.tmp"
    other = tmp_path / f".u.ply.{dead.pid}.abc123.tmp"
    for p in (stale, live, other):
        p.write_bytes(b"partial")
    jaxmesh.save(jaxmesh.Mesh.from_arrays(*tetrahedron_arrays()), tmp_path / "t.ply")
    assert not stale.exists() and live.exists() and other.exists()


@pytest.mark.slow   # two fresh CLI processes and a bunny denoise (~15 s)
@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")],
                         ids=["SIGINT", "SIGTERM"])
def test_ctrl_c_stops_a_long_denoise_within_seconds(tmp_path, sig, code, word):
    out = tmp_path / "out.ply"
    argv = [sys.executable, "-m", "jaxmesh.cli", "denoise", "--sample", "bunny", str(out), "--method", "kernel"]
    start = time.perf_counter()  # how long imports, load and compile take on this machine now
    subprocess.run(argv + ["--iterations", "3"], capture_output=True, check=True)
    startup = time.perf_counter() - start
    out.unlink()
    proc = subprocess.Popen(WITH_SIGINT + argv[1:] + ["--iterations", "100000"], stderr=subprocess.PIPE, text=True)
    time.sleep(2 * startup + 2)  # the loop is running
    assert proc.poll() is None
    start = time.perf_counter()
    proc.send_signal(sig)
    try:
        _, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail(f"denoise ignored {sig.name} for 30 s")
    assert time.perf_counter() - start < 10
    assert proc.returncode == code and word in err
    assert list(tmp_path.iterdir()) == []


def test_the_eager_loop_is_the_compiled_loop(tetra):
    import jax

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        eager = METHODS["taubin"](tetra, iterations=37).vertices
        rings = METHODS["taubin"].host_inputs["rings"](tetra)     # arguments, as the kept program gets them
        jitted = jax.jit(lambda v, r: METHODS["taubin"](tetra.with_vertices(v), iterations=37, rings=r).vertices)(
            tetra.vertices, rings)
        one_less = METHODS["taubin"](tetra, iterations=36).vertices
    # one fori_loop either way: the same program, so the same bits; one step more or
    # less moves the vertices (here 4.9e-10: the tetrahedron is nearly collapsed)
    np.testing.assert_array_equal(np.asarray(eager), np.asarray(jitted))
    assert np.max(np.abs(np.asarray(one_less) - np.asarray(jitted))) > 1e-11


def test_concurrent_writers_never_clobber(tmp_path):
    """16 threads write the same new file at once: exactly one wins, the others get
    FileExistsError, the file holds one writer's bytes whole, no temporary file is left."""
    import threading

    from jaxmesh.io import write_bytes_atomic

    target = tmp_path / "t.bin"
    outcome = {}
    go = threading.Barrier(16)

    def writer(k):
        go.wait()
        try:
            write_bytes_atomic(target, bytes([k]) * 100_000)
            outcome[k] = "wrote"
        except FileExistsError:
            outcome[k] = "refused"

    threads = [threading.Thread(target=writer, args=(k,)) for k in range(16)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    winners = [k for k, v in outcome.items() if v == "wrote"]
    assert len(outcome) == 16 and len(winners) == 1
    assert target.read_bytes() == bytes([winners[0]]) * 100_000
    assert [p.name for p in tmp_path.iterdir()] == ["t.bin"]


def test_a_reference_of_another_connectivity_is_named_not_broadcast(tmp_path, capsys):
    """Before: "operands could not be broadcast together with shapes (4,4) (2,2)"."""
    from conftest import grid_arrays

    a, b = tmp_path / "tet.ply", tmp_path / "grid.ply"
    jaxmesh.save(jaxmesh.Mesh.from_arrays(*tetrahedron_arrays()), a)
    v, f = grid_arrays(1, 1)
    jaxmesh.save(jaxmesh.Mesh.from_arrays(v, f), b)
    code, err = _cli(capsys, "denoise", a, tmp_path / "o.ply", "--method", "taubin", "--reference", b)
    assert code == 1 and err == [f"jaxmesh: error: --reference {b} does not have the connectivity of {a}"]


def test_a_far_vertex_is_named_and_a_run_that_spreads_it_is_an_error(tmp_path, capsys, tetra):
    from jaxmesh.transforms import far_vertices

    v = np.vstack([np.asarray(tetra.vertices), [[1e30, 0.0, 0.0]]])
    f = np.vstack([np.asarray(tetra.faces), [[1, 4, 2]]])
    far = jaxmesh.Mesh.from_arrays(v, f, warn=False)          # its far face reads as degenerate
    np.testing.assert_array_equal(far_vertices(far), [4])
    assert far_vertices(jaxmesh.data.load_sample("spot", dtype=np.float64)).size == 0
    unused = jaxmesh.Mesh.from_arrays(v, np.asarray(tetra.faces), warn=False)      # an isolated far vertex: no
    assert far_vertices(unused).size == 0                                          # frame uses it
    path = tmp_path / "far.ply"
    jaxmesh.save(far, path)
    assert main(["denoise", str(path), str(tmp_path / "out.ply"), "--method", "taubin", "--iterations", "1"]) == 1
    err = capsys.readouterr().err
    assert "1 vertex(es) lie more than 1e4 times the typical distance" in err
    assert "jaxmesh: error: taubin diverged" in err and "vertex 4 lies far from the rest" in err   # spread, not silent
    assert not (tmp_path / "out.ply").exists()

"""`jaxmesh compress` and `jaxmesh decompress`: JSON output, --info, refusals, truncated
files, and the same bytes and vertices when each runs in a fresh process."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import jaxmesh
from jaxmesh.cli import main

REPO = Path(__file__).resolve().parents[2]


def test_cli_compress_decompress_info_and_force(tmp_path, capsys):
    out = tmp_path / "s.jxm"
    assert main(["compress", "--sample", "spot", str(out), "--keep", "0.1", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["bits_per_vertex"] == pytest.approx(8 * out.stat().st_size / rec["vertices"])
    assert main(["compress", "--sample", "spot", str(out)]) == 1
    assert "exists" in capsys.readouterr().err
    assert main(["decompress", "--info", "--json", str(out)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["vertices"] == rec["vertices"] and info["connectivity_coder"] == "traversal"
    assert main(["decompress", str(out), str(tmp_path / "s.obj")]) == 0
    bad = tmp_path / "bad.jxm"
    bad.write_bytes(out.read_bytes()[:50])
    assert main(["decompress", str(bad), str(tmp_path / "x.ply")]) == 1
    assert "truncated" in capsys.readouterr().err
    assert not (tmp_path / "x.ply").exists()


def _worker(code: str) -> dict:
    """Run Python in a fresh process (JAX and numpy state not shared with the tests)."""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO,
                         env={**os.environ, "JAX_PLATFORMS": "cpu"}, timeout=300)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow   # two fresh Python processes (JAX import + compile each); the in-process CLI tests cover the commands
def test_round_trip_through_the_cli_in_separate_processes(tmp_path, spot):
    src = tmp_path / "spot.ply"
    jaxmesh.save(spot, src)
    jxm, back = tmp_path / "spot.jxm", tmp_path / "back.ply"
    for args in (["compress", str(src), str(jxm), "--keep", "0.15", "--bits", "11", "--patch-size", "800"],
                 ["decompress", str(jxm), str(back)]):
        r = subprocess.run([sys.executable, "-m", "jaxmesh", *args], capture_output=True, text=True, cwd=REPO,
                           timeout=300)
        assert r.returncode == 0, r.stderr
    # the in-memory reconstruction of the same settings, computed here
    c = jaxmesh.compress.compress(spot, keep=0.15, bits=11, patch_size=800)
    assert jxm.read_bytes() == c.data
    got = jaxmesh.load(back)
    np.testing.assert_array_equal(np.asarray(got.faces), np.asarray(c.mesh.faces))
    np.testing.assert_allclose(np.asarray(got.vertices), np.asarray(c.mesh.vertices), rtol=0, atol=1e-12)
    v = np.asarray(spot.vertices)[c.order]
    err_file = np.sqrt(np.mean(np.sum((v - np.asarray(got.vertices)) ** 2, 1)))
    err_mem = np.sqrt(np.mean(np.sum((v - np.asarray(c.mesh.vertices)) ** 2, 1)))
    assert err_file == pytest.approx(err_mem, rel=1e-12)
    # and a second fresh process decodes the same bytes to the same vertices, bit for bit
    import hashlib

    res = _worker("import hashlib, json, jax; jax.config.update('jax_enable_x64', True); "
                  f"import numpy as np, jaxmesh; m = jaxmesh.compress.load_compressed({str(jxm)!r}); "
                  "v = np.asarray(m.vertices); print(json.dumps({'dtype': str(v.dtype), "
                  "'sha': hashlib.sha256(v.tobytes()).hexdigest()}))")
    assert res == {"dtype": "float64", "sha": hashlib.sha256(np.asarray(c.mesh.vertices).tobytes()).hexdigest()}



"""`jaxmesh hash`: one mesh's hash as JSON (equal to the library's), two meshes
compared with the verdict and its threshold, and the refusals."""

import json

import pytest

import jaxmesh
from jaxmesh.cli import main
from jaxmesh.hashing import attacks, robust_hash


def test_cli_hash_and_compare(capsys, tmp_path, spot):
    assert main(["hash", "--json", "--sample", "spot"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["kind"] == "robust" and out["vector"] == [float(x) for x in robust_hash(spot).vector]
    a, b = tmp_path / "a.ply", tmp_path / "b.ply"
    jaxmesh.save(spot, a)
    jaxmesh.save(attacks.rotate(spot, "x", 45), b)
    assert main(["hash", "--compare", str(a), str(b)]) == 0
    line = capsys.readouterr().out
    assert "same model" in line and "threshold rho >= 0.5" in line
    assert main(["hash", "--compare", str(a), str(b), "--method", "thesis", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["rho"] == pytest.approx(1.0, abs=1e-9) and rec["same_model"] is True
    assert main(["hash", "--compare", str(a), str(b), str(a)]) == 1
    assert "exactly two" in capsys.readouterr().err
    assert main(["hash", str(tmp_path / "absent.ply")]) == 1

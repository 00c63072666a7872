"""`jaxmesh train`: a model from real pairs, usable by `jaxmesh denoise --method learned
--model`; pairs matched by file name with clear errors; outputs never overwritten
unless asked."""

import shutil

import numpy as np
import pytest
import trimesh

import jaxmesh
from jaxmesh.cli import main
from jaxmesh.learn import learned_denoising, load_model
from conftest import write_pairs


@pytest.mark.slow      # compiles the default model's training step (about 18 s on 2 cores)
def test_train_on_pairs_then_denoise_with_the_model(capsys, tmp_path):
    write_pairs(tmp_path, 3)
    model = tmp_path / "m.jxl"
    curve = tmp_path / "curve.png"
    args = ["train", str(tmp_path / "clean"), "--noisy", str(tmp_path / "in"), "-o", str(model), "--steps", "2",
            "--batch", "2", "--validate", "1", "--validate-every", "1", "--curve", str(curve)]
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "training on 2 mesh(es), validating on 1" in err and "validation" in err
    assert curve.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (tmp_path / "m.jxl.ckpt").exists(), "the checkpoint is removed at the end"
    trained = load_model(model)
    out = tmp_path / "out.ply"
    assert main(["denoise", str(tmp_path / "in" / "p0.ply"), str(out), "--method", "learned",
                 "--model", str(model)]) == 0
    noisy = jaxmesh.load(tmp_path / "in" / "p0.ply")
    np.testing.assert_allclose(jaxmesh.load(out).vertices, learned_denoising(noisy, trained).vertices,
                               rtol=1e-9, atol=1e-12)
    assert main(args) == 1
    assert "exists; use --force" in capsys.readouterr().err


def test_unmatched_or_mismatched_pairs_are_errors_naming_the_file(capsys, tmp_path):
    write_pairs(tmp_path, 2)
    out = str(tmp_path / "m.jxl")
    shutil.copy(tmp_path / "clean" / "p0.ply", tmp_path / "clean" / "extra.ply")
    assert main(["train", str(tmp_path / "clean"), "--noisy", str(tmp_path / "in"), "-o", out]) == 1
    assert "extra.ply: in CLEAN_DIR but not in NOISY_DIR" in capsys.readouterr().err
    (tmp_path / "clean" / "extra.ply").unlink()
    other = trimesh.creation.icosphere(subdivisions=2)
    jaxmesh.save(jaxmesh.Mesh.from_arrays(other.vertices, other.faces), str(tmp_path / "in" / "p1.ply"),
                 overwrite=True)
    assert main(["train", str(tmp_path / "clean"), "--noisy", str(tmp_path / "in"), "-o", out]) == 1
    assert "p1.ply: the noisy mesh does not have the clean mesh's connectivity" in capsys.readouterr().err
    assert main(["train", str(tmp_path / "nowhere"), "-o", out]) == 1
    assert "is not a directory" in capsys.readouterr().err
    assert main(["train", str(tmp_path / "clean"), "-o", out, "--sigma", "0.5", "0.1"]) == 1
    assert "--sigma must be 0 < LO <= HI" in capsys.readouterr().err
    assert main(["train", str(tmp_path / "clean"), "-o", out, "--validate", "2"]) == 1
    assert "--validate must leave at least one training mesh" in capsys.readouterr().err

"""Every script in examples/ runs end to end (in this process, on the shipped samples)
and prints what it promises."""

import runpy
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
EXPECT = {   # a line each example must print
    "denoise_a_scan": "choose_denoiser picked",
    "denoise_a_folder": "4 meshes denoised, 0 failed",
    "compress_vs_draco": "bits/vertex",
    "hash_under_attacks": "the bunny",
    "statistics_figure": "average_degree",
    "gradient_through_a_flow": "central difference",
}


@pytest.mark.slow   # about 45 s together; .ci/run runs them
@pytest.mark.filterwarnings("ignore::jaxmesh.MeshWarning")
@pytest.mark.filterwarnings("ignore::jaxmesh.tune.BlindTuningWarning")
@pytest.mark.parametrize("name", sorted(EXPECT))
def test_example_runs(name, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", [f"{name}.py", "--out", str(tmp_path)])
    monkeypatch.syspath_prepend(str(EXAMPLES))
    runpy.run_path(str(EXAMPLES / f"{name}.py"), run_name="__main__")
    assert EXPECT[name] in capsys.readouterr().out


def test_every_example_is_tested_and_recorded():
    scripts = {p.stem for p in EXAMPLES.glob("*.py")} - {"_common", "run_all"}
    assert scripts == set(EXPECT)
    recorded = {p.stem for p in (EXAMPLES.parent / "docs" / "examples-output").glob("*.txt")}
    assert recorded == scripts, "run examples/run_all.py to record the outputs the docs show"

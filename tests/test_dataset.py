"""The dataset runner (jaxmesh.dataset): buckets cover every mesh once, outputs equal
per-mesh calls, an interrupted run resumes without redoing or losing outputs.  Its
command line (``jaxmesh denoise --out-dir``: bad files reported and skipped, several
processes) is tested in tests/cli/test_cli_denoise.py."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import pytest

import jaxmesh
from jaxmesh.dataset import (LADDER_RATIO, PACK_SEGMENTS, denoise_files, expand_inputs, output_pairs, plan_batches,
                             plan_packs, rung)
from jaxmesh.denoise import denoise_in_unit_frame
from conftest import assert_refused, write_dataset, write_pairs


def test_rung_is_the_least_ladder_size_above():
    sizes = [rung(n) for n in range(1, 5000)]
    assert all(s >= n for n, s in zip(range(1, 5000), sizes))
    assert LADDER_RATIO == 2 ** 0.5 and rung(64, 2 ** 0.25) == 64 and rung(65, 2 ** 0.25) == 77
    assert sizes == sorted(sizes) and rung(64) == 64 and rung(65) == 91       # ⌈64 √2⌉
    assert all(s <= max(64, LADDER_RATIO * n + 1) for n, s in zip(range(1, 5000), sizes))
    assert len(set(sizes)) == 1 + int(np.ceil(2 * np.log2(5000 / 64)))   # 14 shapes for 1 to 5000 vertices


def test_plan_covers_every_mesh_once_and_buckets_share_a_shape():
    rng = np.random.default_rng(0)
    v = rng.integers(10, 20000, 300)
    sizes = [(int(n), int(2 * n - rng.integers(0, 5)), int(3 * n + rng.integers(0, 9))) for n in v]
    plan = plan_batches(sizes, batch_size=8)
    seen = sorted(i for b in plan for i in b.items)
    assert seen == list(range(300))
    for b in plan:
        assert 1 <= len(b.items) <= 8 and len(b.items) + b.fill in (1, 2, 4, 8)
        for i in b.items:
            nv, nf, ne = sizes[i]
            assert b.shape[0] > nv and b.shape[1] >= nf and b.shape[2] > ne   # one padding vertex and edge
    shapes = {b.shape for b in plan}
    assert len(shapes) == len({b.shape[0] for b in plan})                  # one shape per vertex bucket
    with pytest.raises(ValueError, match="batch_size"):
        plan_batches(sizes, batch_size=0)


def test_packs_hold_every_mesh_once_within_capacity_and_share_shapes():
    rng = np.random.default_rng(1)
    v = np.exp(rng.uniform(np.log(20), np.log(3000), 400)).astype(int)
    sizes = [(int(n), 2 * int(n) - 4, 3 * int(n) - 6) for n in v] + [(9000, 17996, 26994)]   # one above capacity
    plan = plan_packs(sizes, capacity=4096, segments=16)
    assert sorted(i for b in plan for i in b.items) == list(range(len(sizes)))
    for b in plan:
        total = [sum(sizes[i][d] for i in b.items) for d in range(3)]
        assert b.packed and b.fill == 0 and len(b.items) <= 15
        assert b.shape[0] > total[0] and b.shape[1] >= total[1] and b.shape[2] > total[2]
        assert total[0] + 1 <= 4096 or b.items == (len(sizes) - 1,)      # the large mesh is a union of its own
        assert b.shape == (rung(total[0] + 1), rung(total[1]), rung(total[2] + 1))
    # first fit: at most one union is half empty (unless it holds its most meshes)
    half = [b for b in plan if 2 * sum(sizes[i][0] for i in b.items) <= 4095 and len(b.items) < 15]
    assert len(half) <= 1
    for bad in ({"capacity": 1}, {"segments": 1}):
        with pytest.raises(ValueError, match=f"{next(iter(bad))} must be an int"):
            plan_packs(sizes, **bad)
    assert_refused(plan_packs, sizes, capacity=2.5, param="capacity", message="capacity must be an int")


@pytest.mark.filterwarnings("ignore::jaxmesh.mesh.MeshWarning")
@pytest.mark.parametrize("method,params", [("taubin", {"iterations": 7}), ("cotangent", {"dt": 0.3})])
def test_packed_runs_equal_per_mesh_calls(tmp_path, method, params):
    """The default for a local method: the meshes run as disjoint unions, one program."""
    paths = write_dataset(tmp_path / "in", 7)
    s = denoise_files([str(tmp_path / "in")], tmp_path / "out", method, params)
    assert (s.done, s.skipped, s.failed) == (7, 0, 0) and s.compiles == 1     # one union of the seven
    for p in paths:
        want = denoise_in_unit_frame(jaxmesh.load(str(p)), method, **params)
        got = jaxmesh.load(str(tmp_path / "out" / p.name))
        np.testing.assert_allclose(got.vertices, want.vertices, rtol=0, atol=1e-12 * (1 + int(p.stem[1:])))
        np.testing.assert_array_equal(got.faces, want.faces)


def test_pack_is_refused_where_it_cannot_run(tmp_path):
    paths = write_dataset(tmp_path / "in", 1)
    for method, kw, why in (("cauchy_diffusion", {}, "reduces over the whole mesh"), ("auto", {}, "mesh by mesh"),
                            ("taubin", {"params": {"lam": "auto"}}, "tuned per mesh"),
                            ("taubin", {"batch_size": 2}, "not both")):
        with pytest.raises(ValueError, match=why):
            denoise_files(paths, tmp_path / "out", method, pack=True, **kw)
    assert not (tmp_path / "out").exists()
    assert PACK_SEGMENTS >= 2


@pytest.mark.filterwarnings("ignore::jaxmesh.mesh.MeshWarning")
@pytest.mark.parametrize("method,params", [
    ("taubin", {"iterations": 7}),
    pytest.param("kernel", {"lam": 0.02, "iterations": 3}, marks=pytest.mark.slow),
    pytest.param("bilateral_normal", {"normal_iterations": 2, "vertex_iterations": 3}, marks=pytest.mark.slow)])
def test_outputs_equal_per_mesh_calls(tmp_path, method, params, monkeypatch):
    """Also with every compiled program dropped after each batch (as past the mapping limit)."""
    import jaxmesh.dataset.runner as runner

    released = []
    monkeypatch.setattr(runner, "release_compiled_programs",
                        lambda: released.append(jaxmesh.compiler.release_compiled_programs(limit=0)))
    paths = write_dataset(tmp_path / "in", 3 if method == "bilateral_normal" else 7)   # compiled per mesh
    s = denoise_files([str(tmp_path / "in")], tmp_path / "out", method, params, batch_size=2)
    assert (s.done, s.skipped, s.failed) == (len(paths), 0, 0)
    assert all(released) and len(released) >= 2                 # after each batch
    assert method != "bilateral_normal" or len(released) == len(paths)     # mesh by mesh: one batch each
    for p in paths:
        want = denoise_in_unit_frame(jaxmesh.load(str(p)), method, **params)
        got = jaxmesh.load(str(tmp_path / "out" / p.name))
        np.testing.assert_allclose(got.vertices, want.vertices, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(got.faces, want.faces)
    if method != "bilateral_normal":                  # face-graph filters run mesh by mesh
        assert 1 <= s.compiles <= len(paths) and s.waste > 0


def test_the_reader_threads_errors_reach_the_consumer():
    """An unexpected error on the read-ahead thread (here in the padding step) is
    raised in the loop that consumes it, not left as a hang on an empty queue."""
    from jaxmesh.dataset.plan import Batch
    from jaxmesh.dataset.streams import read_ahead

    plan = [Batch((0,), 0, (0, 0, 0)), Batch((1,), 0, (0, 0, 0))]

    def prepare(batch, meshes):
        if batch.items == (1,):
            raise MemoryError("no room to pad")
        return "padded"

    got = read_ahead(plan, [("a", "x"), ("b", "y")], lambda path: path.upper(), prepare)
    assert next(got) == (plan[0], ["A"], "padded")
    with pytest.raises(MemoryError, match="no room"):
        next(got)


@pytest.mark.filterwarnings("ignore::jaxmesh.mesh.MeshWarning")
def test_an_interrupted_run_resumes_without_redoing_or_losing_outputs(tmp_path):
    paths = write_dataset(tmp_path / "in", 8)
    seen = []

    def stop_after_two_batches(done, total):
        seen.append(done)
        if len(seen) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        denoise_files([str(tmp_path / "in")], tmp_path / "out", "taubin", batch_size=2,
                      progress=stop_after_two_batches)
    first = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "out").iterdir()}
    assert 0 < len(first) < len(paths) and not list((tmp_path / "out").glob(".*.tmp"))
    s = denoise_files([str(tmp_path / "in")], tmp_path / "out", "taubin", batch_size=2)
    assert s.skipped == len(first) and s.done == len(paths) - len(first) and s.failed == 0
    for p in paths:
        out = tmp_path / "out" / p.name
        if p.name in first:
            assert out.stat().st_mtime_ns == first[p.name]           # not redone
        want = denoise_in_unit_frame(jaxmesh.load(str(p)), "taubin")
        np.testing.assert_allclose(jaxmesh.load(str(out)).vertices, want.vertices, atol=1e-12)


def test_a_report_that_fails_midway_stops_the_report_not_the_outputs_and_is_an_error(tmp_path):
    """The write-behind thread whose report fails (a full disk) keeps saving every result, never
    blocks the run (more jobs than its queue holds), and close() raises the report's error, named;
    end to end, /dev/full as the report: every output written, then the error."""
    import errno

    from jaxmesh.dataset.streams import Report, Writer

    class Full(Report):
        def write(self, record):
            raise OSError(errno.ENOSPC, "No space left on device", "r.jsonl")

    saved = []
    writer = Writer(lambda mesh, path, overwrite: saved.append(path), False, Full(None))
    for k in range(200):                                     # the queue holds 64
        writer.put(None, k, {})
    with pytest.raises(OSError, match="report stopped there") as err:
        writer.close()
    assert saved == list(range(200)) and err.value.filename == "r.jsonl"
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full on this system for the end-to-end check")
    paths = write_dataset(tmp_path / "in", 3)
    with pytest.raises(OSError, match="No space left on device") as err:
        denoise_files(paths, tmp_path / "out", "taubin", report="/dev/full")
    assert err.value.filename == "/dev/full"
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(p.name for p in paths)


@pytest.mark.filterwarnings("ignore::jaxmesh.mesh.MeshWarning")
def test_an_output_written_meanwhile_by_another_run_is_skipped_not_failed_nor_replaced(tmp_path):
    """Two runs into one folder: the outputs the other run wrote while this one computed are
    counted as skipped (not failed, and not replaced); simulated by writing every missing
    output once this run's first output is written."""
    paths = write_dataset(tmp_path / "in", 4)
    out = tmp_path / "out"

    def other_run(done, total):
        if done == 1:
            deadline = time.monotonic() + 60
            while not list(out.glob("*.ply")) and time.monotonic() < deadline:    # this run's first output
                time.sleep(0.01)
            for p in paths:
                if not (out / p.name).exists():
                    (out / p.name).write_text("the other run's")

    s = denoise_files(paths, out, "taubin", batch_size=1, progress=other_run, report=tmp_path / "r.jsonl")
    assert (s.done, s.skipped, s.failed) == (1, 3, 0)
    assert sum((out / p.name).read_bytes() == b"the other run's" for p in paths) == 3
    lines = [json.loads(line) for line in (tmp_path / "r.jsonl").read_text().splitlines()]
    assert sorted(r["status"] for r in lines) == ["ok", "skipped", "skipped", "skipped"]


def test_an_output_that_is_its_own_input_is_refused_unless_overwrite(tmp_path):
    paths = write_dataset(tmp_path / "in", 2)
    before = [p.read_bytes() for p in paths]
    with pytest.raises(ValueError, match="would be the input file itself .2 of 2"):
        denoise_files(paths, tmp_path / "in", "taubin")
    assert [p.read_bytes() for p in paths] == before
    assert output_pairs(paths, tmp_path / "in", ".obj") == [(p, p.with_suffix(".obj")) for p in paths]
    s = denoise_files(paths, tmp_path / "in", "taubin", overwrite=True)      # in place, asked for
    assert s.done == 2 and all(p.read_bytes() != b for p, b in zip(paths, before))


def test_inputs_from_files_directories_and_globs(tmp_path):
    (tmp_path / "d").mkdir()
    for name in ("b.ply", "a.obj", "c.txt"):
        (tmp_path / "d" / name).write_text("")
    got = expand_inputs([str(tmp_path / "d"), str(tmp_path / "d" / "*.ply"), str(tmp_path / "d" / "a.obj")])
    assert [p.name for p in got] == ["a.obj", "b.ply"]


def test_bad_arguments_are_refused_before_any_work(tmp_path):
    with pytest.raises(ValueError, match="no input meshes"):
        denoise_files([str(tmp_path / "*.ply")], tmp_path / "out")
    with pytest.raises(ValueError, match="chooses its own parameters"):
        denoise_files([str(tmp_path)], tmp_path / "out", "auto", {"lam": 1.0})
    with pytest.raises(ValueError, match="suffix"):
        denoise_files([str(tmp_path)], tmp_path / "out", "taubin", suffix=".png")
    for ladder in (1.0, float("inf"), float("nan")):     # inf was an OverflowError
        with pytest.raises(ValueError, match="ladder ratio"):
            denoise_files([str(tmp_path)], tmp_path / "out", "taubin", ladder=ladder)
    for report, message in ((tmp_path / "missing" / "r.jsonl", "does not exist"), (tmp_path, "is a directory")):
        with pytest.raises(ValueError, match=f"report .*{message}"):
            denoise_files([str(tmp_path)], tmp_path / "out", "taubin", report=report)
    assert not (tmp_path / "out").exists()
    with pytest.raises(ValueError, match="only continuous parameters"):
        denoise_files([str(tmp_path)], tmp_path / "out", "taubin", {"iterations": "auto"})
    with pytest.raises(ValueError, match="pad_to"):
        jaxmesh.batch.pad_batch([jaxmesh.Mesh.from_arrays(np.eye(3), np.array([[0, 1, 2]]))], (3, 1, 4))


@pytest.mark.slow   # 60 s: tuning compiles per batch shape, and again per mesh for the reference
@pytest.mark.filterwarnings("ignore::jaxmesh.mesh.MeshWarning")
@pytest.mark.filterwarnings("ignore::jaxmesh.tune.BlindTuningWarning")
def test_lam_auto_tunes_each_mesh_as_tune_does(tmp_path):
    """``lam="auto"``: blind tuning per mesh in padded batches (tune_batch); each
    output and λ equal :func:`jaxmesh.tune.tune` on that mesh alone."""
    from jaxmesh.tune import tune

    paths = write_dataset(tmp_path / "in", 3)
    s = denoise_files([str(tmp_path / "in")], tmp_path / "out", "kernel", {"lam": "auto", "iterations": 2},
                      batch_size=2)
    assert (s.done, s.failed) == (3, 0)
    for p, rec in zip(paths, sorted(s.records, key=lambda r: r["input"])):
        want = tune(jaxmesh.load(str(p)), None, "kernel", names=["lam"], iterations=2)
        assert rec["params"]["lam"] == pytest.approx(float(want.params["lam"]), rel=1e-6)
        np.testing.assert_allclose(jaxmesh.load(str(tmp_path / "out" / p.name)).vertices, want.mesh.vertices,
                                   atol=1e-9)



@pytest.mark.slow   # 5 s; the default run has the command's (tests/cli: --reference with --tune-on)
def test_references_and_one_setting_tuned_on_a_subset(tmp_path):
    """``tune_on=2`` with references: λ tuned once (tune_shared, supervised) on the
    first two inputs and applied to all; every report line has the errors before and
    after against its clean twin, or says why it has none."""
    from jaxmesh.metrics import error_summary
    from jaxmesh.tune import tune_shared

    names = write_pairs(tmp_path, 3)
    (tmp_path / "clean" / names[2]).unlink()                       # one input without a reference
    s = denoise_files([str(tmp_path / "in")], tmp_path / "out", "kernel", {"lam": "auto", "iterations": 2},
                      batch_size=2, reference=tmp_path / "clean", tune_on=2)
    assert (s.done, s.failed) == (3, 0)
    load = lambda *p: jaxmesh.load(str(tmp_path.joinpath(*p)))   # noqa: E731
    want = tune_shared([load("in", n) for n in names[:2]], [load("clean", n) for n in names[:2]], "kernel",
                       names=["lam"], iterations=2)
    lam = float(want.params["lam"])
    records = sorted(s.records, key=lambda r: r["input"])
    for name, rec in zip(names, records):
        assert rec["tuned_on"]["supervised"] and [p.split("/")[-1] for p in rec["tuned_on"]["files"]] == names[:2]
        assert rec["params"] == {"lam": pytest.approx(lam, rel=1e-12), "iterations": 2}
        out = load("out", name)
        np.testing.assert_allclose(out.vertices, denoise_in_unit_frame(load("in", name), "kernel", lam=lam,
                                                                       iterations=2).vertices, atol=1e-12)
        if name == names[2]:
            assert "before" not in rec and "no clean mesh named p2.*" in rec["reference_error"]
            continue
        assert rec["before"] == pytest.approx(error_summary(load("clean", name), load("in", name)), rel=1e-12)
        assert rec["after"] == pytest.approx(error_summary(load("clean", name), out), rel=1e-12)
        assert rec["after"]["normal_angle_deg"] < rec["before"]["normal_angle_deg"]


def test_reference_and_tune_on_refusals(tmp_path):
    names = write_pairs(tmp_path, 2)
    run = lambda params, **kw: denoise_files([str(tmp_path / "in")], tmp_path / "out", "taubin", params, **kw)  # noqa: E731
    with pytest.raises(ValueError, match="is not a folder"):
        run({}, reference=tmp_path / "nowhere")
    with pytest.raises(ValueError, match="no parameter is 'auto'"):
        run({"lam": 0.5}, tune_on=2)
    with pytest.raises(ValueError, match="tune_on must be an integer"):
        run({"lam": "auto"}, tune_on=-1)
    (tmp_path / "clean" / names[1]).unlink()
    with pytest.raises(ValueError, match=f"no clean mesh in .* for .*{names[1]}"):
        run({"lam": "auto"}, tune_on=2, reference=tmp_path / "clean")
    (tmp_path / "in" / names[0]).write_text("ply\nformat ascii 1.0\nelement vertex 9\nend_header\n0 0\n")
    with pytest.raises(ValueError, match=f"training input .*{names[0]} cannot be read"):
        run({"lam": "auto"}, tune_on=1)
    assert not (tmp_path / "out").exists()


@pytest.mark.filterwarnings("ignore::jaxmesh.mesh.MeshWarning")
def test_a_mesh_with_a_far_vertex_fails_alone_named_and_the_others_keep_their_frames(tmp_path):
    """One input with a corrupt coordinate (1e30) in a batched run: that input fails with the
    vertex named (its far vertex, found on the host, leaves the frame; the flow spreads it); the
    others give what they give alone."""
    paths = write_dataset(tmp_path / "in", 3)
    bad = jaxmesh.load(str(paths[1]))
    v = np.asarray(bad.vertices).copy()
    v[2, 0] = 1e30
    jaxmesh.save(bad.with_vertices(v), paths[1], overwrite=True)
    for pack, kw in ((False, {"batch_size": 2}), (True, {})):       # padded batches and one packed union
        _far_vertex_run(tmp_path / f"out{pack}", paths, kw)


def _far_vertex_run(out, paths, kw):
    s = denoise_files(paths, out, "taubin", **kw)
    assert (s.done, s.failed) == (2, 1)
    failed = [r for r in s.records if r["status"] == "failed"]
    assert failed[0]["input"] == str(paths[1]) and "vertex 2 lies far from the rest" in failed[0]["error"]
    for p in (paths[0], paths[2]):
        want = denoise_in_unit_frame(jaxmesh.load(str(p)), "taubin")
        np.testing.assert_allclose(jaxmesh.load(str(out / p.name)).vertices, want.vertices, atol=1e-12)

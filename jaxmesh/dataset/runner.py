"""Denoising whole datasets: size buckets, one compiled program per bucket
shape, reads ahead and writes behind, a JSON-lines report, resumable, with
failures isolated.

Planning (files, sizes, buckets): :mod:`.plan`; the padded batches and their
programs: :mod:`._batched`.

**Runs.**  Every mesh is denoised in its own unit frame (:func:`~jaxmesh.
transforms.unit_frame`, as the CLI does), with one method and one parameter
setting for all.  Methods that need a per-mesh auxiliary input (the
face-graph filters) and ``method="auto"`` run mesh by mesh, still in the same
stream.  Outputs are written atomically, so a rerun skips every output that
exists (complete by construction) unless ``overwrite``; a mesh that cannot be
read, is invalid, or diverges is reported with its reason and the rest go on.

**Streams.**  Two passes over the files: the first learns every mesh's sizes
from its header (PLY, OFF: :func:`peek_sizes`; other formats are read and
dropped), the second reads each batch on a reader thread one batch ahead of
the computation and writes results on a writer thread, so memory is bounded
by a few batches, not by the dataset.  A batch whose meshes turn out larger
than their headers said gets the next ladder size (one more compile).
"""

from __future__ import annotations

import dataclasses
import functools
import time
from pathlib import Path
from typing import Any
from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp

from ..compiler import release_compiled_programs
from ..mesh import Mesh
from . import supervision
from ._batched import Outcome, Tally, pad_group, precompile, run_batch, tuned_keys, tuned_values
from .streams import Report, Writer, read_ahead
from .plan import (LADDER_RATIO, LADDER_START, MESH_SUFFIXES, Batch, default_batch_size, output_pairs, peek_sizes,
                   plan_batches, plan_packs, rung)

__all__ = ["DatasetSummary", "denoise_files"]


@dataclasses.dataclass(frozen=True)
class DatasetSummary:
    """What :func:`denoise_files` did: counts, the ``compiles`` (distinct
    programs run), ``waste`` (padded vertex slots over real ones), wall
    ``seconds``, and one ``records`` dict per input (also the report's lines)."""

    done: int
    skipped: int
    failed: int
    compiles: int
    waste: float
    seconds: float
    records: list

    def as_dict(self) -> dict[str, Any]:
        return {"done": self.done, "skipped": self.skipped, "failed": self.failed, "compiles": self.compiles,
                "padding_waste": self.waste, "seconds": self.seconds}


def _check(method: str, params: dict, suffix: str | None) -> str:
    """The method's registry name, every parameter checked before any file is read."""
    from ..denoise import METHODS, as_method

    if method == "auto":
        if set(params) - {"ladder"}:
            raise ValueError("method 'auto' chooses its own parameters; give none (but the search's 'ladder')")
        from ..tune.ladder import check_ladder

        check_ladder(params.get("ladder"))
    else:
        m = as_method(method)
        if METHODS.get(m.name) is not m:
            raise ValueError("denoise_files takes a registered method name (or 'auto')")
        for k in tuned_keys(params):
            if k not in m.params or m.params[k].kind != "continuous":
                raise ValueError(f"{k}='auto': only continuous parameters of {m.name} can be tuned "
                                 f"({', '.join(n for n, q in m.params.items() if q.kind == 'continuous')})")
        m.resolve(**{k: v for k, v in params.items() if k not in tuned_keys(params)})
        method = m.name
    if suffix is not None and suffix.lower() not in MESH_SUFFIXES:
        raise ValueError(f"suffix must be one of {MESH_SUFFIXES}, got {suffix!r}")
    return method


def _collect(inputs, out_dir: Path, suffix: str | None, overwrite: bool, method: str, index: int, count: int):
    """(this share's inputs and outputs, one record each); existing outputs are
    marked skipped.  Name clashes and in-place outputs are checked over all shares."""
    items = output_pairs(inputs, out_dir, suffix, overwrite=overwrite)[index::count]
    records = [{"input": str(src), "output": str(out), "method": method} for src, out in items]
    for rec, (_, out) in zip(records, items):
        if out.exists() and not overwrite:
            rec["status"] = "skipped"
    return items, records


def _read_sizes(items: list[tuple[Path, Path]], load: Callable, records: list) -> dict[int, tuple[int, int, int]]:
    """First pass: {k: (V, F, E)} of every input k that can be read, from its header where it
    has one (E estimated as V + F, Euler's V − E + F = χ with χ ≈ 0), else by loading it; a file
    that fails to load becomes a failed record."""
    sizes = {}
    for k, (src, _) in enumerate(items):
        peek = peek_sizes(src)
        if peek is not None and min(peek) > 0:
            sizes[k] = (peek[0], peek[1], peek[0] + peek[1])
            continue
        try:
            m = load(src)
            sizes[k] = (m.num_vertices, m.num_faces, m.num_edges)
        except (ValueError, OSError) as err:
            records[k].update(status="failed", error=f"{type(err).__name__}: {err}")
    return sizes


def _run_single(mesh, method: str, params: dict, record: dict) -> Outcome:
    """One mesh by itself (auto, or a method with auxiliary inputs; the reader gives a mesh or the exception)."""
    from ..denoise import denoise_in_unit_frame

    if not isinstance(mesh, Mesh):
        return Outcome(error=mesh)
    try:
        names = tuned_keys(params) if method != "auto" else []
        if names:
            from ..tune import tune

            r = tune(mesh, None, method, names=names, **{k: params[k] for k in params if k not in names})
            return Outcome(r.mesh, tuned_values(params, {n: r.params[n] for n in names}))
        if method != "auto":
            return Outcome(denoise_in_unit_frame(mesh, method, **params))
        from ..tune import choose_denoiser

        choice = choose_denoiser(mesh, ladder=params.get("ladder"))
        record.update(chosen=choice.method, params=choice.params)
        if choice.method == "blend":
            record["components"] = [{"method": m, "params": p, "weight": w} for m, p, w in choice.components]
        return Outcome(choice.mesh)
    except (ValueError, FloatingPointError) as err:
        return Outcome(error=err)


def denoise_files(inputs: Sequence[str | Path], out_dir: str | Path, method: str = "taubin",
                  params: dict | None = None, *, batch_size: int | None = None, ladder: float = LADDER_RATIO,
                  overwrite: bool = False,
                  suffix: str | None = None, report: str | Path | None = None,
                  progress: Callable[[int, int], None] | None = None,
                  share: tuple[int, int] | None = None, reference: str | Path | None = None,
                  tune_on: int = 0, pack: bool | None = None) -> DatasetSummary:
    """Denoise every mesh of ``inputs`` into ``out_dir`` in size buckets (module
    docstring): one compiled program per (padded size, batch size).

    Arguments:
        inputs: files, directories and glob patterns (:func:`expand_inputs`).
        out_dir: the output folder (same file names).
        method: a registered method (``"auto"`` tunes per mesh).
        params: the method's parameters; a continuous one may be ``"auto"``.  With ``"auto"``, only
            ``{"ladder": R}``: the search mesh padded to that ladder (:func:`~jaxmesh.tune.choose_denoiser`).
        batch_size: meshes per compiled call (default :func:`~jaxmesh.dataset.plan.default_batch_size`:
            1 on CPU, 16 on an accelerator).
        ladder: the ratio between padded sizes (larger: fewer compiles, more padding).
        overwrite: redo inputs whose output exists (default: skip them, so an
            interrupted run resumes).
        suffix: the output format (default: the input's).
        report: a JSON-lines file, one line per input, appended to as the run goes.
        progress: called as ``progress(done, total)`` after each batch.
        share: ``(i, n)``: this process takes every n-th input from the i-th (default
            ``(jax.process_index(), jax.process_count())``, so after
            ``jax.distributed.initialize`` each process denoises its own share).
        reference: a folder of clean meshes (same file names): each report line gets
            the errors before and after (:mod:`.supervision`).
        tune_on: tune the ``"auto"`` parameters once on the first ``tune_on`` inputs
            (against ``reference`` when given, else blind) and apply that setting to
            all (default 0: each mesh tuned blind by itself).
        pack: run the meshes as disjoint unions (:func:`~jaxmesh.dataset.plan.plan_packs`), not
            padded batches.  Default: when the method is ``packable``, no parameter is tuned per
            mesh and no ``batch_size`` is given; True where it cannot is an error.

    Returns:
        A :class:`DatasetSummary` (counts, compiles, padding waste, seconds, one
        record per input)."""
    from ..denoise import METHODS
    from ..io import load

    start = time.perf_counter()
    params = dict(params or {})
    method = _check(method, params, suffix)
    packs = _packs(method, params, pack, batch_size)
    rung(LADDER_START + 1, ladder)            # the ladder checked before any file is read
    out_dir = Path(out_dir)
    index, count = share if share is not None else (jax.process_index(), jax.process_count())
    if not 0 <= index < count:
        raise ValueError(f"share {share}: the index must be in [0, count)")
    folder = supervision.check(reference, tune_on, tuned_keys(params), method != "auto" and bool(METHODS[method].aux))
    log = Report(report)                      # refused here, before any work, if it cannot be written
    items, records = _collect(inputs, out_dir, suffix, overwrite, method, index, count)
    if tune_on:
        params, training = supervision.tune_on_subset(inputs, tune_on, method, params, tuned_keys(params), folder, load)
        records = [{**rec, "tuned_on": training} for rec in records]
    out_dir.mkdir(parents=True, exist_ok=True)
    todo, sizes = _first_pass(items, records, load, log)
    batched = method != "auto" and not METHODS[method].aux
    plan = _plan(sizes, todo, batch_size, ladder, packs) if batched else [Batch((k,), 0, (0, 0, 0)) for k in todo]
    ahead = batched and not tuned_keys(params)
    compiled = precompile(plan, method, params, jnp.result_type(float)) if ahead else {}
    tally, writer, finished = Tally(), Writer(_save_keeping, overwrite, log), 0
    try:
        prepare = functools.partial(pad_group, ladder=ladder) if batched else None
        for batch, meshes, prepared in read_ahead(plan, items, load, prepare):
            t0 = time.perf_counter()
            results = (run_batch(batch, meshes, prepared, method, params, tally, compiled) if batched
                       else {batch.items[0]: _run_single(meshes[0], method, params, records[batch.items[0]])})
            seconds = round((time.perf_counter() - t0) / len(batch.items), 4)
            for k, noisy in zip(batch.items, meshes):
                _settle(records[k], results[k], noisy, items[k], params, seconds, writer, log, folder)
            finished += len(batch.items)
            release_compiled_programs()
            if progress is not None:
                progress(finished, len(todo))
    finally:   # what was computed is written, even when interrupted
        writer.close()
    return _summary(records, tally, start)


def _first_pass(items: list, records: list, load: Callable, log: Report) -> tuple[list[int], dict]:
    """(the inputs still to do that could be read, their (V, F, E) sizes); every record
    settled so far (skipped, unreadable) goes to the report."""
    todo = [k for k, rec in enumerate(records) if "status" not in rec]
    sizes = {todo[j]: s for j, s in _read_sizes([items[k] for k in todo], load, [records[k] for k in todo]).items()}
    for rec in records:
        if "status" in rec:
            log.write(rec)
    return [k for k in todo if k in sizes], sizes


def _packs(method: str, params: dict, pack: bool | None, batch_size: int | None) -> bool:
    """Whether the run packs its meshes into disjoint unions (``pack`` in :func:`denoise_files`)."""
    from ..denoise import METHODS

    why = ("method 'auto' runs mesh by mesh" if method == "auto" else
           f"{method} reduces over the whole mesh (not Method.packable)" if not METHODS[method].packable else
           "parameters tuned per mesh need padded batches" if tuned_keys(params) else None)
    if pack is None:
        return why is None and batch_size is None
    if pack and why is not None:
        raise ValueError(f"cannot pack the meshes (pack=True, --pack): {why}")
    if pack and batch_size is not None:
        raise ValueError("cannot pack the meshes with a batch size (a union holds as many meshes as fit): give "
                         "pack=True (--pack) or batch_size (--batch-size), not both")
    return bool(pack)


def _plan(sizes: dict, todo: list[int], batch_size: int | None, ladder: float, packs: bool = False) -> list[Batch]:
    """The padded batches (or packed unions) of the inputs ``todo`` (indices into the records),
    from the (V, F, E) ``sizes`` the first pass read."""
    batch_size = default_batch_size() if batch_size is None else batch_size
    plan = (plan_packs([sizes[k] for k in todo], ratio=ladder) if packs
            else plan_batches([sizes[k] for k in todo], batch_size, ladder))
    return [dataclasses.replace(b, items=tuple(todo[i] for i in b.items)) for b in plan]


def _settle(rec: dict, outcome: Outcome, noisy, item: tuple, params: dict, seconds: float, writer: Writer,
            log: Report, folder: Path | None) -> None:
    """Record one input's fate: a result goes to the writer (scored against its
    reference there, when there is a reference folder), a failure to the report."""
    from ..io import load

    if outcome.error is not None:
        rec.update(status="failed", error=f"{type(outcome.error).__name__}: {outcome.error}")
        log.write(rec)
        return
    result = outcome.mesh
    if outcome.params is not None:
        rec["params"] = outcome.params
    rec.update(status="ok", vertices=result.num_vertices, faces=result.num_faces, seconds=seconds)
    rec.setdefault("params", params)
    check = None if folder is None else functools.partial(supervision.score, rec, noisy, result, item[0], folder, load)
    writer.put(result, item, rec, check)


def _save_keeping(mesh: Mesh, item: tuple, overwrite: bool) -> None:
    """Save to the output of ``item`` (input, output), keeping what the input file carries besides
    positions and triangles where the output has its format and its layout can be rewritten
    (:mod:`jaxmesh.attributes`); else positions and triangles only."""
    from ..attributes import read_attributes
    from ..io import save

    source, out = item
    keep = None
    if Path(source).suffix.lower() == Path(out).suffix.lower():
        try:
            keep = read_attributes(source)
        except ValueError:
            keep = None
    save(mesh, out, overwrite=overwrite, attributes=keep)


def _summary(records: list, tally: Tally, start: float) -> DatasetSummary:
    count = lambda s: sum(r["status"] == s for r in records)   # noqa: E731
    waste = (tally.padded - tally.real) / tally.real if tally.real else 0.0
    return DatasetSummary(count("ok"), count("skipped"), count("failed"), len(tally.programs), waste,
                          round(time.perf_counter() - start, 3), records)

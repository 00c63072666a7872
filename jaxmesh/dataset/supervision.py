"""Clean references and shared tuning for the dataset runner.

* **References.**  ``reference`` names a folder of clean meshes; the clean twin of
  an input ``IN/name.ext`` is ``reference/name.ext``, else ``reference/name`` with
  another mesh suffix.  Each output's report line gets the errors
  (:func:`jaxmesh.metrics.error_summary`) of the input and of the result against it,
  as ``before`` and ``after``; an input without a usable twin (missing, unreadable,
  other connectivity) gets ``reference_error`` instead, and is still denoised.
* **Tuning on a subset.**  ``tune_on = N``: the parameters given as ``"auto"`` are
  tuned once, on the first N inputs in the runner's order (the same N in every
  process), by :func:`jaxmesh.tune.tune_shared` — against their references when a
  reference folder is given (every training input must have one), else blind — and
  the one setting found is applied to every input.
"""

from __future__ import annotations

from pathlib import Path

from .plan import MESH_SUFFIXES, expand_inputs

__all__ = ["check", "reference_path", "score", "tune_on_subset"]


def check(reference, tune_on, tuned: list[str], aux: bool) -> Path | None:
    """Refuse bad ``reference`` / ``tune_on`` arguments before any file is read.

    Arguments:
        reference: the folder of clean meshes, or None.
        tune_on: the training-set size (0: none).
        tuned: the parameters given as ``"auto"``.
        aux: whether the method needs per-mesh auxiliary inputs (it cannot be padded).

    Returns:
        The reference folder as a Path, or None."""
    folder = None if reference is None else Path(reference)
    if folder is not None and not folder.is_dir():
        raise ValueError(f"reference: {folder} is not a folder")
    if not (isinstance(tune_on, int) and not isinstance(tune_on, bool) and tune_on >= 0):
        raise ValueError(f"tune_on must be an integer >= 0, got {tune_on!r}")
    if tune_on and not tuned:
        raise ValueError("tune_on: no parameter is 'auto'; nothing to tune")
    if tune_on and aux:
        raise ValueError("tune_on pads meshes of different sizes, which this method (it needs a per-mesh face "
                         "graph) does not support")
    return folder


def reference_path(source: Path, folder: Path) -> Path | None:
    """The clean twin of ``source`` in ``folder``: the same file name, else the same
    stem with another mesh suffix; None when there is none.

    Arguments:
        source: an input mesh file.
        folder: the folder of clean meshes.

    Returns:
        The twin's path, or None."""
    for suffix in (source.suffix, *MESH_SUFFIXES):
        path = folder / (source.stem + suffix)
        if path.is_file():
            return path
    return None


def score(record: dict, noisy, result, source: Path, folder: Path, load) -> None:
    """Add ``reference``, ``before`` and ``after`` (the errors of ``noisy`` and of
    ``result`` against ``source``'s clean twin) to ``record``, or ``reference_error``.

    Arguments:
        record: the input's report line (updated in place).
        noisy: the input mesh.
        result: the denoised mesh.
        source: the input's path.
        folder: the folder of clean meshes.
        load: the mesh reader (:func:`jaxmesh.load`).

    Returns:
        None."""
    from ..metrics import error_summary

    path = reference_path(source, folder)
    if path is None:
        record["reference_error"] = f"no clean mesh named {source.stem}.* in {folder}"
        return
    try:
        clean = load(path)
    except (ValueError, OSError) as err:
        record["reference_error"] = f"{path}: {type(err).__name__}: {err}"
        return
    if not clean.same_connectivity(noisy):
        record["reference_error"] = f"{path} does not have the input's connectivity"
        return
    record.update(reference=str(path), before=error_summary(clean, noisy), after=error_summary(clean, result))


def tune_on_subset(inputs, count: int, method: str, params: dict, names: list[str], folder: Path | None,
                   load) -> tuple[dict, dict]:
    """Tune ``names`` once on the first ``count`` inputs (module docstring).

    Arguments:
        inputs: the runner's inputs (files, directories, globs), all processes' shares.
        count: how many of them to train on (the first ones, in the runner's order).
        method: a registered method without auxiliary inputs.
        params: its parameters; those in ``names`` are ``"auto"``.
        names: the parameters to tune.
        folder: the clean meshes (supervised), or None (blind).
        load: the mesh reader.

    Returns:
        (the parameters with each tuned one's value, a description of the training for
        the report: the files, ``supervised``, the training loss and the parameters)."""
    from ..tune import tune_shared

    files = expand_inputs([str(p) for p in inputs])[:count]
    noisy = []
    for f in files:
        try:
            noisy.append(load(f))
        except (ValueError, OSError) as err:   # the training set must be whole: refuse, naming the file
            raise ValueError(f"tune_on: training input {f} cannot be read ({err})") from None
    clean = None
    if folder is not None:
        twins = [reference_path(f, folder) for f in files]
        missing = [str(f) for f, t in zip(files, twins) if t is None]
        if missing:
            raise ValueError(f"tune_on: no clean mesh in {folder} for {', '.join(missing)}")
        clean = [load(t) for t in twins]
    fixed = {k: v for k, v in params.items() if k not in names}
    result = tune_shared(noisy, clean, method, names=names, **fixed)
    values = {**fixed, **{n: float(result.params[n]) for n in names}}
    return values, {"files": [str(f) for f in files], "supervised": clean is not None,
                    "loss": float(result.error), "params": values}

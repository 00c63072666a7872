"""Planning a dataset run: which files, their sizes, and the packed unions or padded batch shapes.

**Unions** (methods with ``Method.packable``): :func:`plan_packs` puts the meshes,
largest first, into the first union with room (first-fit decreasing) for at most
:data:`PACK_VERTICES` vertices and :data:`PACK_SEGMENTS` − 1 meshes; at most one union
is left half empty.  Each union is padded to the ladder sizes (below) of its totals,
so full unions share one shape and one compiled program (on 200 meshes of 1k–60k
vertices: 56 unions of one shape).

**Buckets.**  Mesh i has V_i vertices, F_i faces, E_i edges.  Padded sizes are
rounded up a geometric ladder (``LADDER_RATIO`` = √2 apart by default, from
``LADDER_START``), so meshes whose vertex counts round to the same rung share
one padded shape and one compiled program; each dimension wastes at most
ratio − 1 (plus the one padding vertex and edge that
:func:`~jaxmesh.batch.pad_batch` needs).  A bucket is cut into batches of
``batch_size``; its last batch is filled up to the next power of two with
copies of its first mesh (computed, never written), so a bucket compiles at
most log₂(batch_size) + 1 programs.

**Defaults.**  :func:`default_batch_size` is 1 on CPU and 16 on an accelerator:
on CPU a vmapped batch costs what a loop over its meshes costs (per vertex), so
batching buys nothing there, while a batch's shape is its largest member's and
its fill copies are computed too.  On 2 cores, 200 meshes of 1k–60k vertices
(``benchmarks/bench_dataset.py``, one run): batch 16 at 2^¼ took 11.2 s
(padding waste 42%), batch 1 at 2^¼ 10.7 s (9%, 26 compiles), batch 1 at √2
7.9 s (19%, 14 compiles), batch 1 at 2 7.4 s (42%, 8 compiles).  A compile
costs about as much as denoising a few meshes, so the √2 ladder is the default:
a larger dataset amortises more compiles (a finer ladder), a smaller one fewer
(``--ladder 2``).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from collections.abc import Iterable, Sequence

__all__ = ["LADDER_START", "LADDER_RATIO", "PACK_VERTICES", "PACK_SEGMENTS", "default_batch_size", "MESH_SUFFIXES",
           "rung", "Batch", "plan_batches", "plan_packs", "expand_inputs", "output_pairs", "peek_sizes"]

LADDER_START = 64
LADDER_RATIO = 2 ** 0.5
#: the vertices a packed union holds (a larger mesh is a union of one): about 3 edges a
#: vertex, its 184k edges stay under the ladder's 185,364 (2^16 would pad them to 262,145)
PACK_VERTICES = 61_440
#: the segments of every packed union (at most this many meshes less one per union)
PACK_SEGMENTS = 64
MESH_SUFFIXES = (".ply", ".obj", ".off", ".stl")


def default_batch_size() -> int:
    """Meshes per compiled call when none is given: 1 on CPU, 16 on an
    accelerator (module docstring).

    Arguments:

    Returns:
        The batch size for JAX's default backend."""
    import jax

    return 1 if jax.default_backend() == "cpu" else 16


def rung(n: int, ratio: float = LADDER_RATIO) -> int:
    """The smallest ladder size ≥ n: ⌈LADDER_START · ratio^k⌉ for the least k ≥ 0.

    Arguments:
        n: a size (≥ 1).
        ratio: the ladder's step (finite, > 1).

    Returns:
        The ladder size."""
    if not (ratio > 1 and math.isfinite(ratio)):
        raise ValueError(f"the ladder ratio must be a finite number > 1, got {ratio!r}")
    if n <= LADDER_START:
        return LADDER_START
    k = math.ceil(math.log(n / LADDER_START, ratio) - 1e-12)
    size = math.ceil(LADDER_START * ratio ** k)
    return size if size >= n else math.ceil(LADDER_START * ratio ** (k + 1))


@dataclasses.dataclass(frozen=True)
class Batch:
    """One call of a compiled program: ``items`` (indices into the plan's sizes,
    the real meshes), ``fill`` copies of the first item added to reach the
    batch's size, and the padded (vertices, faces, edges) ``shape``."""

    items: tuple[int, ...]
    fill: int
    shape: tuple[int, int, int]
    #: one disjoint union of the items (:func:`~jaxmesh.batch.pack_batch`), not a padded stack
    packed: bool = False


def _pow2_at_least(n: int) -> int:
    return 1 << max(0, (n - 1).bit_length())


def plan_batches(sizes: Sequence[tuple[int, int, int]], batch_size: int = 16,
                 ratio: float = LADDER_RATIO) -> list[Batch]:
    """Group meshes of (V, F, E) ``sizes`` into batches (module docstring): every
    index appears in exactly one batch; batches of one bucket share a shape.
    ``ratio``: the ladder's step (fewer shapes and compiles, more padding).

    Arguments:
        sizes: (V, F, E) of every mesh.
        batch_size: the most meshes per batch.
        ratio: the ladder's step (> 1; larger: fewer shapes and compiles, more padding).

    Returns:
        The :class:`Batch` list (mesh indices, fill copies, padded shape)."""
    if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1:
        raise ValueError(f"batch_size must be a positive int, got {batch_size!r}")
    buckets: dict[int, list[int]] = {}
    for i, (v, _, _) in enumerate(sizes):
        buckets.setdefault(rung(v + 1, ratio), []).append(i)
    out = []
    for v_pad in sorted(buckets):
        members = buckets[v_pad]
        shape = (v_pad, rung(max(sizes[i][1] for i in members), ratio),
                 rung(max(sizes[i][2] for i in members) + 1, ratio))
        for start in range(0, len(members), batch_size):
            chunk = tuple(members[start:start + batch_size])
            out.append(Batch(chunk, min(batch_size, _pow2_at_least(len(chunk))) - len(chunk), shape))
    return out


def plan_packs(sizes: Sequence[tuple[int, int, int]], capacity: int = PACK_VERTICES,
               ratio: float = LADDER_RATIO, segments: int = PACK_SEGMENTS) -> list[Batch]:
    """Group meshes of (V, F, E) ``sizes`` into disjoint unions (module docstring):
    first-fit decreasing by vertex count into unions of at most ``capacity`` vertices
    (one padding vertex included) and ``segments`` − 1 meshes; a larger mesh is a union
    of its own.  Each union is padded to the ladder sizes of its totals, so full unions
    share one shape and one compiled program.

    Arguments:
        sizes: (V, F, E) of every mesh.
        capacity: the most vertices per union.
        ratio: the ladder's step for the unions' padded sizes.
        segments: the segments of every union (its meshes plus the padding's).

    Returns:
        The :class:`Batch` list (``packed`` set; mesh indices; the union's padded shape)."""
    if isinstance(capacity, bool) or not isinstance(capacity, int) or capacity < 2:
        raise ValueError(f"capacity must be an int ≥ 2, got {capacity!r}")
    if isinstance(segments, bool) or not isinstance(segments, int) or segments < 2:
        raise ValueError(f"segments must be an int ≥ 2, got {segments!r}")
    bins: list[list[int]] = []
    room: list[int] = []
    for i in sorted(range(len(sizes)), key=lambda i: -sizes[i][0]):
        v = sizes[i][0]
        k = next((k for k, r in enumerate(room) if r >= v and len(bins[k]) < segments - 1), None)
        if k is None:
            bins.append([])
            room.append(capacity - 1)
            k = len(bins) - 1
        bins[k].append(i)
        room[k] -= v
    out = []
    for members in bins:
        total = [sum(sizes[i][d] for i in members) for d in range(3)]
        shape = (rung(total[0] + 1, ratio), rung(total[1], ratio), rung(total[2] + 1, ratio))
        out.append(Batch(tuple(members), 0, shape, packed=True))
    return out


def expand_inputs(paths: Iterable[str]) -> list[Path]:
    """Files named directly, every mesh file (by suffix) in a named directory
    (sorted, not recursive), or the matches of a glob pattern; each once, in order.

    Arguments:
        paths: file names, directories and glob patterns.

    Returns:
        The mesh files, each once, in order."""
    out: list[Path] = []
    for p in paths:
        path = Path(p)
        if path.is_dir():
            found = sorted(q for q in path.iterdir() if q.suffix.lower() in MESH_SUFFIXES and q.is_file())
        elif any(ch in p for ch in "*?["):
            anchor = Path(path.anchor) if path.is_absolute() else Path(".")
            found = sorted(anchor.glob(str(path.relative_to(anchor)) if path.is_absolute() else p))
        else:
            found = [path]
        out += [q for q in found if q not in out]
    return out


def output_pairs(inputs: Iterable[str | Path], out_dir: str | Path, suffix: str | None = None, *,
                 overwrite: bool = False) -> list[tuple[Path, Path]]:
    """Each input file (:func:`expand_inputs`) with its output: ``out_dir / (stem + suffix)``,
    the suffix the input's by default.  Two inputs with one output name are refused, and so is
    an output that is its own input unless ``overwrite`` (denoising in place).

    Arguments:
        inputs: files, directories and glob patterns.
        out_dir: the output folder.
        suffix: the outputs' suffix (default: each input's).
        overwrite: whether outputs may replace existing files, the inputs among them.

    Returns:
        (input, output) per input file, in order."""
    files = expand_inputs([str(p) for p in inputs])
    if not files:
        raise ValueError("no input meshes found")
    pairs = [(src, Path(out_dir) / (src.stem + (suffix or src.suffix))) for src in files]
    outs = [out for _, out in pairs]
    if len(set(outs)) != len(outs):
        raise ValueError("two inputs map to the same output name; give them distinct stems")
    same = [src for src, out in pairs if out.exists() and src.exists() and out.samefile(src)]
    if same and not overwrite:
        raise ValueError(f"{same[0]}: its output would be the input file itself ({len(same)} of {len(pairs)} "
                         "inputs); choose another output folder or suffix (overwrite=True, CLI: --force, "
                         "denoises in place)")
    return pairs


def peek_sizes(path: Path) -> tuple[int, int] | None:
    """(vertices, faces) from a PLY or OFF header (the first 64 KiB), or None when
    the file is of another format or its header cannot be read that way.  An
    estimate for planning only: the mesh is checked when it is loaded.

    Arguments:
        path: a mesh file.

    Returns:
        (vertices, faces) from the header, or None."""
    suffix = path.suffix.lower()
    try:
        with open(path, "rb") as fh:
            head = fh.read(65536).decode("latin-1")
        if suffix == ".ply":
            counts = {}
            for line in head.split("end_header")[0].splitlines():
                tok = line.split()
                if len(tok) == 3 and tok[0] == "element":
                    counts[tok[1]] = int(tok[2])
            return (counts["vertex"], counts["face"]) if "end_header" in head else None
        if suffix == ".off":
            lines = [ln.split("#")[0].strip() for ln in head.splitlines()]
            lines = [ln for ln in lines if ln]
            first = lines[0][3:].split() if lines[0].startswith("OFF") else None
            tok = first if first else lines[1].split()
            return int(tok[0]), int(tok[1])
    except (OSError, ValueError, KeyError, IndexError):
        return None
    return None

"""Fuzz suite: malformed OBJ, OFF, PLY and STL files through :func:`jaxmesh.load`.

A small closed mesh (an icosphere, 42 vertices) is written in each format by
jaxmesh and mutated by case index.  Each mutation knows what a correct reader
must do:

* ``error``: ``MeshFileError`` (truncation inside a line or a binary record,
  NaN/inf/overflowing coordinates, bad/zero/out-of-range indices, wrong
  counts, garbage in a number or a keyword, header counts of 10^12);
* ``same``: load the original mesh exactly (a byte-order mark, a Latin-1 or
  UTF-8 comment, CRLF line ends, UTF-16, garbage inside a comment);
* ``prefix``: a text file cut at a line end may load, but then as the first
  vertices and faces of the original, or fail with ``MeshFileError``;
* ``polygon``: a quad appended: the original faces plus two triangles.

Outcomes: ``valid`` (what the mutation says), ``error`` (a ``MeshFileError``
where one is expected), ``silent`` (a mesh that is not what the file says,
or an error where the file was valid), ``traceback`` (another exception).
"""

from __future__ import annotations

import atexit
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np

FORMATS = ("obj", "off", "ply", "stl_ascii", "stl")
KINDS = ("truncate", "nan", "huge", "overflow", "index", "count", "polygon", "bom", "comment", "crlf",
         "utf16", "garbage", "garbage_comment", "bigcount", "empty_lines")
_GARBAGE = b"@!?$%&*;:<>[]{}|~^`"


def setup():
    import jax

    jax.config.update("jax_enable_x64", True)
    import trimesh

    import jaxmesh
    from jaxmesh import _meshtext as T

    s = trimesh.creation.icosphere(subdivisions=1)
    v, f = np.asarray(s.vertices, np.float64), np.asarray(s.faces, np.int64)
    mesh = jaxmesh.Mesh.from_arrays(v, f)
    tmp = Path(tempfile.mkdtemp(prefix="jaxmesh-fuzz-mesh-"))
    atexit.register(shutil.rmtree, tmp, ignore_errors=True)
    jaxmesh.save(mesh, tmp / "base.ply")
    stl_ascii = "solid s\n" + "".join(
        "facet normal 0 0 0\nouter loop\n" + "".join("vertex %.17g %.17g %.17g\n" % tuple(v[i]) for i in t)
        + "endloop\nendfacet\n" for t in f) + "endsolid s\n"
    base = {
        "obj": T.write_obj(v, f), "off": T.write_off(v, f), "ply": (tmp / "base.ply").read_bytes(),
        "stl_ascii": stl_ascii.encode(), "stl": T.write_stl(v, f),
    }
    return {"v": v, "f": f, "base": base, "tmp": tmp}


def _data_lines(data: bytes, fmt: str):
    """Byte offsets (start, end) of the lines that carry numbers."""
    out, pos = [], 0
    for line in data.split(b"\n"):
        t = line.strip()
        if t and t[:1].isdigit() or t[:1] == b"-" or t.startswith((b"v ", b"f ", b"vertex")):
            out.append((pos, pos + len(line)))
        pos += len(line) + 1
    return out


def mutate(state, i: int):
    rng = np.random.default_rng(i)
    fmt = FORMATS[i % len(FORMATS)]
    kind = KINDS[(i // len(FORMATS)) % len(KINDS)]
    data = state["base"][fmt]
    binary = fmt in ("ply", "stl")
    text_part = data[:data.find(b"end_header") + 11] if fmt == "ply" else (data[:80] if fmt == "stl" else data)
    label = f"{fmt} {kind}"
    if kind == "truncate":
        n = int(rng.integers(1, len(data)))
        if binary:
            return f"{label} to {n}", data[:n], "error"
        at_line_end = data[n - 1:n] == b"\n"
        return f"{label} to {n}", data[:n], ("prefix" if at_line_end else "error")
    if binary and kind in ("nan", "huge", "overflow", "index", "garbage", "garbage_comment", "comment", "crlf",
                           "utf16", "empty_lines", "polygon"):
        # binary payloads carry no redundancy: mutate what can be checked
        if fmt == "ply" and kind in ("nan", "overflow"):
            header_end = len(text_part)
            pos = header_end + 8 * int(rng.integers(0, 3 * len(state["v"])))
            val = np.array([np.nan if kind == "nan" else np.inf], "<f8").tobytes()
            return label, data[:pos] + val + data[pos + 8:], "error"
        if fmt == "ply" and kind == "index":
            header_end = len(text_part) + 24 * len(state["v"])
            k = int(rng.integers(0, len(state["f"])))
            pos = header_end + 13 * k + 1 + 4 * int(rng.integers(0, 3))
            bad = int(rng.choice([len(state["v"]), -1, 2**31 - 1]))
            return label, data[:pos] + np.array([bad], "<i4").tobytes() + data[pos + 4:], "error"
        if fmt == "stl" and kind == "nan":
            pos = 84 + 50 * int(rng.integers(0, len(state["f"]))) + 12 + 4 * int(rng.integers(0, 9))
            return label, data[:pos] + np.array([np.nan], "<f4").tobytes() + data[pos + 4:], "error"
        return f"{label} (unchanged)", data, "same"
    if kind == "count":
        if fmt == "ply":
            which = rng.choice([b"element vertex 42", b"element face 80"])
            new = which.split(b" ")[0] + b" " + which.split(b" ")[1] + b" %d" % int(rng.integers(43, 500))
            return label, data.replace(which, new, 1), "error"
        if fmt == "off":
            lines = data.split(b"\n")
            nv, nf, ne = lines[1].split()
            lines[1] = b" ".join([nv, str(int(nf) + int(rng.integers(1, 5))).encode(), ne]) if rng.random() < 0.5 \
                else b" ".join([str(int(nv) - int(rng.integers(1, 5))).encode(), nf, ne])
            return label, b"\n".join(lines), "error"
        if fmt == "stl":
            n = int.from_bytes(data[80:84], "little") + int(rng.integers(1, 100))
            return label, data[:80] + n.to_bytes(4, "little") + data[84:], "error"
        # obj / ascii stl: drop one face corner
        lines = _data_lines(data, fmt)
        start, end = lines[-2]
        line = data[start:end]
        cut = line.rsplit(b" ", 1)[0]
        return label, data[:start] + cut + data[end:], ("error" if fmt == "obj" or b"vertex" in line else "error")
    if kind == "bigcount":
        if fmt == "ply":
            return label, data.replace(b"element vertex 42", b"element vertex 1000000000000", 1), "error"
        if fmt == "off":
            return label, data.replace(b"42 80 0", b"1000000000000 80 0", 1), "error"
        if fmt == "stl":
            return label, data[:80] + (2**32 - 1).to_bytes(4, "little") + data[84:], "error"
        return f"{label} (unchanged)", data, "same"
    if kind in ("nan", "huge", "overflow"):
        lines = [(a, b) for a, b in _data_lines(data, fmt) if not data[a:b].strip().startswith(b"f ")
                 and not (fmt == "off" and data[a:b].strip().startswith(b"3 "))]
        if fmt == "off":
            lines = lines[1:]  # the counts line
        a, b = lines[int(rng.integers(len(lines)))]
        toks = data[a:b].split(b" ")
        j = len(toks) - 1 - int(rng.integers(0, 3))
        toks[j] = {"nan": rng.choice([b"nan", b"NaN", b"inf", b"-inf"]), "huge": b"1e300",
                   "overflow": b"1e400"}[kind]
        return label, data[:a] + b" ".join(toks) + data[b:], ("huge" if kind == "huge" else "error")
    if kind == "index":
        lines = [(a, b) for a, b in _data_lines(data, fmt) if data[a:b].startswith((b"f ", b"3 "))]
        if not lines:
            return f"{label} (unchanged)", data, "same"
        a, b = lines[int(rng.integers(len(lines)))]
        toks = data[a:b].split(b" ")
        n = len(state["v"])
        bad = int(rng.choice([0, -n - 1, n + 1, n + 1000, 2**40])) if fmt == "obj" else \
            int(rng.choice([-1, n, n + 1000, 2**40]))
        toks[1 + int(rng.integers(0, 3))] = str(bad).encode()
        return label, data[:a] + b" ".join(toks) + data[b:], "error"
    if kind == "polygon":
        n = len(state["v"])
        if fmt == "obj":
            return label, data + b"f 1 2 3 4\n", "polygon"
        if fmt == "off":
            lines = data.split(b"\n")
            nv, nf, ne = lines[1].split()
            lines[1] = b" ".join([nv, str(int(nf) + 1).encode(), ne])
            return label, b"\n".join(lines).rstrip(b"\n") + b"\n4 0 1 2 3\n", "polygon"
        return f"{label} (unchanged)", data, "same"
    if kind == "bom":
        return label, b"\xef\xbb\xbf" + data, ("error" if binary else "same")
    if kind == "comment":
        comment = rng.choice([b"# caf\xe9 (latin-1)\n", "# café ☃ (utf-8)\n".encode()])
        if fmt == "off":
            return label, data.replace(b"\n", b"\n" + comment, 1), "same"
        if fmt == "stl_ascii":
            return f"{label} (unchanged)", data, "same"
        return label, comment + data, "same"
    if kind == "crlf":
        return label, data.replace(b"\n", b"\r\n"), "same"
    if kind == "utf16":
        return label, b"\xff\xfe" + data.decode("ascii").encode("utf-16-le"), "same"
    if kind == "empty_lines":
        return label, data.replace(b"\n", b"\n\n  \n"), "same"
    if kind == "garbage_comment":
        if fmt == "stl_ascii":
            return f"{label} (unchanged)", data, "same"
        junk = bytes(rng.choice(list(_GARBAGE), int(rng.integers(1, 30))).astype(np.uint8))
        pos = data.find(b"\n") + 1 if fmt == "off" else 0
        return label, data[:pos] + b"#" + junk + b"\n" + data[pos:], "same"
    # garbage: a span of non-numeric bytes replaces bytes inside a data line
    lines = _data_lines(data, fmt)
    a, b = lines[int(rng.integers(len(lines)))]
    start = int(rng.integers(a, b))
    junk = bytes(rng.choice(list(_GARBAGE), int(rng.integers(1, 6))).astype(np.uint8))
    return f"{label} at {start}", data[:start] + junk + data[start + len(junk):], "error"


def case(state, i: int):
    import jaxmesh
    from jaxmesh import MeshFileError

    label, data, expect = mutate(state, i)
    fmt = FORMATS[i % len(FORMATS)]
    path = state["tmp"] / f"case{i}.{fmt.split('_')[0]}"
    path.write_bytes(data)
    v0, f0 = state["v"], state["f"]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = jaxmesh.load(path, dtype=np.float64)
    except MemoryError:
        raise
    except MeshFileError as err:
        path.unlink()
        if expect in ("error", "prefix"):
            return label, ("error", str(err)[-200:])
        return label, ("silent", f"refused a valid file: {err}")
    except Exception as err:  # noqa: BLE001
        path.unlink()
        return label, ("traceback", f"{type(err).__name__}: {err}")
    path.unlink()
    v, f = np.asarray(m.vertices), np.asarray(m.faces)
    if fmt.startswith("stl"):  # STL: triangle soups (float32 when binary), merged on load
        soup0 = v0[f0] if fmt == "stl_ascii" else v0[f0].astype(np.float32).astype(np.float64)
        soup = v[f] if len(f) == len(f0) else None
        if soup is not None and expect == "same" and np.array_equal(soup, soup0):
            return label, "valid"
        if soup is not None and expect == "huge" and (soup != soup0).sum() == 1 and (soup == 1e300).sum() == 1:
            return label, "valid"
        return label, ("silent", f"expected {expect}, loaded {len(v)} vertices {len(f)} faces")
    if expect == "same" and np.array_equal(v, v0) and np.array_equal(f, f0):
        return label, "valid"
    if expect == "huge" and v.shape == v0.shape and np.array_equal(f, f0) and (v == 1e300).sum() == 1 \
            and np.array_equal(v[v != 1e300], v0[v != 1e300]):
        return label, "valid"
    if expect == "prefix" and len(v) <= len(v0) and len(f) <= len(f0) and np.array_equal(v, v0[:len(v)]) \
            and np.array_equal(f, f0[:len(f)]):
        return label, "valid"
    if expect == "polygon" and np.array_equal(v, v0) and np.array_equal(f[:len(f0)], f0) \
            and f[len(f0):].tolist() == [[0, 1, 2], [0, 2, 3]]:
        return label, "valid"
    return label, ("silent", f"expected {expect}, loaded {len(v)} vertices {len(f)} faces")

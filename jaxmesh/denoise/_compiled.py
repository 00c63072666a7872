"""How a method called with concrete inputs runs: as one compiled program, kept for later
calls (not public API).

Called eagerly, a method would run one primitive at a time and trace and compile its
iteration loop again on every call (the loop's body is a new function each time).  So
:meth:`~jaxmesh.denoise.Method.__call__` and
:func:`~jaxmesh.denoise.denoise_in_unit_frame` resolve the parameters on their concrete
values (errors and warnings name them), then call one ``jax.jit`` program with the
continuous parameters traced (a new value does not compile again) and the others static,
the host-built inputs (the face graph, the kernel flow's vertex rings) passed in.
``jax.disable_jit()`` gives the op-by-op run back.

The host-built inputs depend on the connectivity alone, so each builder keeps what it built
for the last connectivity it saw (:func:`host_built`): calls on one mesh (a parameter sweep,
a notebook) build the face graph once.  The key is a digest of every connectivity array, so
a mesh with other faces, even of the same size, builds its own; one entry per builder, and
none larger than :data:`HOST_BUILT_MAX_BYTES`, bound the memory kept between calls.
"""

from __future__ import annotations

import hashlib
import threading

import jax
import numpy as np

from ._loop import reporting

_CONNECTIVITY = ("faces", "edges", "face_edges", "src", "dst", "edge_of", "degree")
#: a host-built input larger than this is not kept between calls (a face graph takes about 300 bytes a face)
HOST_BUILT_MAX_BYTES = 256 << 20
_built: dict = {}
_lock = threading.Lock()


def connectivity_key(mesh) -> tuple:
    """A digest of a single mesh's connectivity arrays (with their shapes and dtypes): equal
    for two meshes exactly when their topologies are (up to a BLAKE2b collision)."""
    digest = hashlib.blake2b(digest_size=20)
    for name in _CONNECTIVITY:
        a = np.ascontiguousarray(getattr(mesh, name))
        digest.update(f"{name}{a.shape}{a.dtype}".encode())
        digest.update(a.data)
    return mesh.num_vertices, digest.hexdigest()


def host_built(build, mesh):
    """``build(mesh)`` for a host builder that reads only the connectivity, kept for the last
    connectivity each builder saw (module docstring); traced connectivity goes to ``build`` as
    it is (which refuses it with its own message)."""
    if any(isinstance(getattr(mesh, name), jax.core.Tracer) for name in _CONNECTIVITY):
        return build(mesh)
    key = connectivity_key(mesh)
    with _lock:
        hit = _built.get(build)
    if hit is not None and hit[0] == key:
        return hit[1]
    value = build(mesh)
    size = sum(int(getattr(leaf, "nbytes", 0)) for leaf in jax.tree_util.tree_leaves(value))
    with _lock:
        if size <= HOST_BUILT_MAX_BYTES:
            _built[build] = (key, value)
        else:                     # too large to hold on to: neither it nor the last mesh's is kept
            _built.pop(build, None)
    return value


def forget_host_built() -> None:
    """Drop every kept host-built input (their memory is released with the last reference)."""
    with _lock:
        _built.clear()


def compilable(m, mesh, params: dict) -> bool:
    """Whether a call of method ``m`` runs as a kept program: not for a method that reads a file
    (its content is not part of a program's key), not inside a progress context (its callback is
    traced into the loop), and not with a traced argument (the caller's program traces it)."""
    return not (reporting() or any(p.kind == "file" for p in m.params.values()) or any(
        isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves((mesh, params))))


def split_call(m, mesh, params: dict) -> tuple[dict, tuple, dict]:
    """(continuous parameters, static parameters as a sorted tuple, host-built inputs) of a call,
    resolved on the given values; the inputs not given are built, those of ``host_inputs`` only
    for one connectivity (``mesh.faces`` (F, 3)), as the method would build them itself."""
    given = {k: v for k, v in params.items() if (k in m.aux or k in m.host_inputs) and v is not None}
    continuous, statics = m.parts(m.resolve(**{k: v for k, v in params.items()
                                               if k not in m.aux and k not in m.host_inputs}))
    builders = {k: m.params[k].build for k in m.aux}
    if mesh.faces.ndim == 2:
        builders.update(m.host_inputs)
    return continuous, statics, {**{k: host_built(b, mesh) for k, b in builders.items() if k not in given},
                                 **given}


def _method_vertices(mesh, continuous: dict, inputs: dict, method, statics: tuple):
    return method.function(mesh, **continuous, **dict(statics), **inputs).vertices


#: one program per method (static by identity) and static parameters
method_program = jax.jit(_method_vertices, static_argnames=("method", "statics"))

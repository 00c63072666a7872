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
"""

from __future__ import annotations

import jax

from ._loop import reporting


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
    return continuous, statics, {**{k: b(mesh) for k, b in builders.items() if k not in given}, **given}


def _method_vertices(mesh, continuous: dict, inputs: dict, method, statics: tuple):
    return method.function(mesh, **continuous, **dict(statics), **inputs).vertices


#: one program per method (static by identity) and static parameters
method_program = jax.jit(_method_vertices, static_argnames=("method", "statics"))

"""XLA's CPU compiler settings for many-compile workloads.

A dataset run compiles one program per padded batch shape, and on CPU those
compiles are much of its time.  XLA's CPU backend (jaxlib 0.10) generates its
fused loops with the MLIR "fusion emitters" by default; the older elemental
emitters, selected by ``--xla_cpu_use_fusion_emitters=false``, compile jaxmesh's
programs in about half the time.  How fast the programs then run depends on
the program (``benchmarks/bench_xla_flags.py``, bunny, float64, 2 cores,
Session 13; steady state, default → flag): the umbrella flow 150 → 107 ms,
Taubin 242 → 219 ms, the kernel flow 486 → 299 ms, bilateral normal filtering
1.20 → 1.00 s, a loop of 16 kernel-flow calls 647 → 419 ms, but a vmapped
batch of those 16 meshes 820 → 998 ms.  (``benchmarks/bench_denoise.py`` in
float32 with and without the flag: the umbrella step 1.06 → 1.80 ms per
iteration, slower.)  The dataset runner, which gives one mesh per call on
CPU, is 1.18× faster with it (``benchmarks/bench_dataset.py``, variant
``runner-xla-defaults``).

XLA reads ``XLA_FLAGS`` once, when JAX's first computation starts its backend,
and aborts on a flag it does not know: :func:`prefer_fast_cpu_compiles` adds the
flag only before that point, only for the jaxlib versions it was measured with,
and never over a setting of the user's.  The ``jaxmesh`` command calls it first
thing; ``JAXMESH_XLA_DEFAULTS=1`` keeps XLA's own defaults.
"""

from __future__ import annotations

import os
import sys

__all__ = ["prefer_fast_cpu_compiles", "CPU_COMPILE_FLAG", "MEASURED_JAXLIB"]

#: the flag added to XLA_FLAGS
CPU_COMPILE_FLAG = "--xla_cpu_use_fusion_emitters=false"
#: jaxlib (major, minor) versions where the flag was measured (older or newer ones are left alone)
MEASURED_JAXLIB = ((0, 10),)


def _backend_started() -> bool:
    xla_bridge = sys.modules.get("jax._src.xla_bridge")
    return bool(getattr(xla_bridge, "_backends", None))


def prefer_fast_cpu_compiles() -> bool:
    """Add :data:`CPU_COMPILE_FLAG` to ``XLA_FLAGS`` when it can still take effect
    and is known to help (module docstring); call before JAX's first computation.

    Arguments:

    Returns:
        True if the flag was added; False if it was left out: ``JAXMESH_XLA_DEFAULTS=1``,
        ``XLA_FLAGS`` already names the setting, the backend has started, or this
        jaxlib version was not measured."""
    flags = os.environ.get("XLA_FLAGS", "")
    if os.environ.get("JAXMESH_XLA_DEFAULTS") == "1" or "xla_cpu_use_fusion_emitters" in flags:
        return False
    if _backend_started():
        return False
    try:
        from importlib.metadata import version

        major, minor = (int(x) for x in version("jaxlib").split(".")[:2])
    except Exception:   # not installed as a distribution, or an unusual version string
        return False
    if (major, minor) not in MEASURED_JAXLIB:
        return False
    os.environ["XLA_FLAGS"] = f"{flags} {CPU_COMPILE_FLAG}".strip()
    return True

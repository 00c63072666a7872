"""jaxmesh.compiler: the CPU compile flag is added only where it can take effect,
never over the user's own setting, and XLA accepts it."""

import os
import subprocess
import sys

import jax.numpy as jnp

from jaxmesh import compiler


def test_left_alone_when_the_user_decides_or_the_backend_runs(monkeypatch):
    jnp.zeros(1).block_until_ready()                    # this process's backend has started
    monkeypatch.setenv("XLA_FLAGS", "--xla_dump_to=/tmp/x")
    assert compiler.prefer_fast_cpu_compiles() is False
    assert os.environ["XLA_FLAGS"] == "--xla_dump_to=/tmp/x"
    monkeypatch.setenv("JAXMESH_XLA_DEFAULTS", "1")
    monkeypatch.setattr(compiler, "_backend_started", lambda: False)
    assert compiler.prefer_fast_cpu_compiles() is False
    monkeypatch.delenv("JAXMESH_XLA_DEFAULTS")
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_use_fusion_emitters=true")
    assert compiler.prefer_fast_cpu_compiles() is False
    assert os.environ["XLA_FLAGS"] == "--xla_cpu_use_fusion_emitters=true"
    monkeypatch.setenv("XLA_FLAGS", "--xla_dump_to=/tmp/x")
    monkeypatch.setattr(compiler, "MEASURED_JAXLIB", ((0, 0),))
    assert compiler.prefer_fast_cpu_compiles() is False


def test_a_fresh_process_gets_the_flag_and_xla_accepts_it():
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAXMESH_XLA_DEFAULTS")}
    code = ("import os, jax.numpy as jnp; from jaxmesh.compiler import prefer_fast_cpu_compiles as p; "
            "print(p()); print(float(jnp.arange(4.0).sum())); print(os.environ['XLA_FLAGS']); print(p())")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.split()
    if lines[0] == "False":     # a jaxlib this setting was not measured with: nothing added
        assert lines[1] == "6.0"
        return
    assert lines == ["True", "6.0", compiler.CPU_COMPILE_FLAG, "False"]

"""jaxmesh.compiler: the CPU compile flag is added only for the jaxlib it was measured
with, never over the user's own setting, and XLA accepts it."""

import os
import subprocess
import sys

from jaxmesh import compiler


def test_left_alone_when_the_user_decides(monkeypatch):
    monkeypatch.setenv("XLA_FLAGS", "--xla_dump_to=/tmp/x")
    monkeypatch.setenv("JAXMESH_XLA_DEFAULTS", "1")
    assert compiler.prefer_fast_cpu_compiles() is False
    assert os.environ["XLA_FLAGS"] == "--xla_dump_to=/tmp/x"
    monkeypatch.delenv("JAXMESH_XLA_DEFAULTS")
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_use_fusion_emitters=true")
    assert compiler.prefer_fast_cpu_compiles() is False
    assert os.environ["XLA_FLAGS"] == "--xla_cpu_use_fusion_emitters=true"
    monkeypatch.setenv("XLA_FLAGS", "--xla_dump_to=/tmp/x")
    monkeypatch.setattr(compiler, "MEASURED_JAXLIB", ((0, 0),))
    assert compiler.prefer_fast_cpu_compiles() is False
    from importlib.metadata import version

    monkeypatch.setattr(compiler, "MEASURED_JAXLIB", (tuple(int(x) for x in version("jaxlib").split(".")[:2]),))
    assert compiler.prefer_fast_cpu_compiles() is True
    assert os.environ["XLA_FLAGS"] == f"--xla_dump_to=/tmp/x {compiler.CPU_COMPILE_FLAG}"


def test_a_fresh_process_gets_the_flag_and_xla_accepts_it():
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "JAXMESH_XLA_DEFAULTS")}
    code = ("import os, jax.numpy as jnp; from jaxmesh.compiler import prefer_fast_cpu_compiles as p; "
            "print(p()); print(float(jnp.arange(4.0).sum())); print(os.environ.get('XLA_FLAGS', '')); print(p())")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.split()
    if lines[0] == "False":     # a jaxlib this setting was not measured with: nothing added
        assert lines[1] == "6.0"
        return
    assert lines == ["True", "6.0", compiler.CPU_COMPILE_FLAG, "False"]


def test_default_cache_dir_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("JAXMESH_CACHE_DIR", str(tmp_path / "c"))
    assert compiler.default_cache_dir() == tmp_path / "c"
    for off in ("off", "0", "NONE", "", " no "):
        monkeypatch.setenv("JAXMESH_CACHE_DIR", off)
        assert compiler.default_cache_dir() is None
        assert compiler.enable_compilation_cache() is None
    monkeypatch.delenv("JAXMESH_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert compiler.default_cache_dir() == tmp_path / "xdg" / "jaxmesh" / "jax"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert compiler.default_cache_dir() == tmp_path / "home" / ".cache" / "jaxmesh" / "jax"


def test_enable_compilation_cache_refuses_bad_settings_and_warns_on_a_bad_folder(tmp_path):
    import pytest

    with pytest.raises(ValueError, match="min_compile_seconds"):
        compiler.enable_compilation_cache(tmp_path, min_compile_seconds=float("nan"))
    with pytest.raises(ValueError, match="max_bytes"):
        compiler.enable_compilation_cache(tmp_path, max_bytes=0)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.warns(UserWarning, match="compilation cache stays off"):
        assert compiler.enable_compilation_cache(blocker / "sub") is None


def _cli(args, env):
    return subprocess.run([sys.executable, "-m", "jaxmesh", *args], env=env, capture_output=True, text=True,
                          timeout=300)


def _entries(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.endswith("-cache"))


def test_the_cli_writes_the_cache_then_reads_it_and_no_cache_leaves_it_alone(tmp_path):
    cache = tmp_path / "cache"
    env = {**os.environ, "JAXMESH_CACHE_DIR": str(cache)}
    out = tmp_path / "n.ply"
    first = _cli(["noise", "--sample", "spot", str(out), "--sigma", "0.2"], env)
    assert first.returncode == 0, first.stderr
    written = _entries(cache)
    assert written                                      # programs were written
    first_bytes = out.read_bytes()
    second = _cli(["noise", "--sample", "spot", str(out), "--sigma", "0.2", "--force"], env)
    assert second.returncode == 0, second.stderr
    assert out.read_bytes() == first_bytes              # the cached programs give the same file
    assert _entries(cache) == written                   # every program was found: none compiled anew
    # --no-cache, and JAXMESH_CACHE_DIR=off: no folder made, nothing written
    other = tmp_path / "other"
    run = _cli(["--no-cache", "noise", "--sample", "spot", str(tmp_path / "m.ply"), "--sigma", "0.2"],
               {**os.environ, "JAXMESH_CACHE_DIR": str(other)})
    assert run.returncode == 0, run.stderr
    assert not other.exists()
    run = _cli(["noise", "--sample", "spot", str(tmp_path / "m.ply"), "--sigma", "0.2", "--force"],
               {**os.environ, "JAXMESH_CACHE_DIR": "off", "HOME": str(other), "XDG_CACHE_HOME": str(other)})
    assert run.returncode == 0, run.stderr
    assert not other.exists()


def test_malloc_arenas_capped_unless_the_user_set_them(monkeypatch):
    import platform

    from jaxmesh.cli import limit_malloc_arenas

    monkeypatch.setenv("MALLOC_ARENA_MAX", "4")
    assert limit_malloc_arenas() is False                 # glibc read the user's own setting
    monkeypatch.delenv("MALLOC_ARENA_MAX")
    glibc = sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc"
    assert limit_malloc_arenas() is glibc


def test_compiled_programs_are_released_past_the_mapping_limit():
    """Below the limit the programs are kept; past it (limit 0) jax.clear_caches drops them, so the
    next call compiles again.  /proc/self/maps exists on the Linux CI."""
    import jax
    import jax.numpy as jnp

    f = jax.jit(lambda x: x * 2 + 1)
    f(jnp.ones(3))
    assert compiler.memory_maps() > 0 and f._cache_size() == 1
    assert not compiler.release_compiled_programs(limit=10**9) and f._cache_size() == 1
    assert compiler.release_compiled_programs(limit=0) and f._cache_size() == 0
    assert float(f(jnp.ones(3))[0]) == 3.0 and f._cache_size() == 1

"""jaxmesh's import graph has no cycle (function-level imports included), and its
public surface is what ``__all__`` says."""

from __future__ import annotations

import ast
import importlib
import pkgutil
from pathlib import Path

import pytest

import jaxmesh

ROOT = Path(jaxmesh.__file__).resolve().parent


def _modules() -> dict[str, Path]:
    out = {}
    for path in ROOT.rglob("*.py"):
        rel = path.relative_to(ROOT.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _resolve(module: str, is_package: bool, node: ast.ImportFrom | ast.Import, known) -> list[str]:
    """Modules of jaxmesh that an import statement loads (the most specific known name)."""
    targets = []
    if isinstance(node, ast.Import):
        targets = [a.name for a in node.names]
    else:
        if node.level:
            base = module.split(".") if is_package else module.split(".")[:-1]
            base = base[:len(base) - node.level + 1]
            prefix = ".".join(base + ([node.module] if node.module else []))
        else:
            prefix = node.module or ""
        for a in node.names:
            full = f"{prefix}.{a.name}"
            targets.append(full if full in known else prefix)
    return [t for t in targets if t in known]


def import_graph() -> dict[str, set[str]]:
    known = _modules()
    graph = {m: set() for m in known}
    for module, path in known.items():
        tree = ast.parse(path.read_text(), str(path))
        is_package = path.name == "__init__.py"
        for node in ast.walk(tree):  # every import, at any depth (function-level too)
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                for target in _resolve(module, is_package, node, known):
                    if target != module and not module.startswith(target + "."):  # a parent package
                        graph[module].add(target)
    return graph


def _cycles(graph):
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_walker_sees_function_level_imports_and_cycles():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(graph) == [["a", "b", "c"]]
    g = import_graph()
    assert "jaxmesh.mesh" in g["jaxmesh.geometry"]
    # the denoise report imports ..denoise inside a function: the walker must see it
    assert "jaxmesh.denoise" in g["jaxmesh.cli._denoise_report"]


def test_no_import_cycles():
    cycles = _cycles(import_graph())
    assert cycles == [], "import cycles: " + "; ".join(" -> ".join(c) for c in cycles)


def _public_modules():
    yield jaxmesh
    for info in pkgutil.walk_packages(jaxmesh.__path__, "jaxmesh."):
        if not info.name.rsplit(".", 1)[-1].startswith("_"):
            yield importlib.import_module(info.name)


@pytest.mark.parametrize("module", list(_public_modules()), ids=lambda m: m.__name__)
def test_every_name_in_all_exists(module):
    for name in getattr(module, "__all__", ()):
        assert hasattr(module, name), f"{module.__name__}.__all__ names {name!r}, which does not exist"


def test_subpackages_are_attributes_and_typed():
    for name in ("batch", "compress", "dataset", "denoise", "hashing", "stats", "tune"):
        assert name in jaxmesh.__all__ and getattr(jaxmesh, name).__name__ == f"jaxmesh.{name}"
    assert (ROOT / "py.typed").is_file()


def test_modules_and_functions_stay_small():
    """House rules: no module over 400 lines, no function over 80."""
    too_long = []
    for path in ROOT.rglob("*.py"):
        text = path.read_text()
        if len(text.splitlines()) > 400:
            too_long.append(f"{path.relative_to(ROOT)}: {len(text.splitlines())} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.end_lineno - node.lineno >= 80:
                too_long.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}: "
                                f"{node.end_lineno - node.lineno + 1} lines")
    assert too_long == []


def test_the_package_and_the_command_lines_help_do_not_import_jax():
    """``import jaxmesh`` and ``jaxmesh --help`` load no JAX (every name is lazy, and the
    command line imports only the command it runs); each lazy name then resolves."""
    import subprocess
    import sys

    code = ("import sys, jaxmesh, jaxmesh.cli; jaxmesh.cli.build_parser(()).format_help(); "
            "assert 'jax' not in sys.modules and 'jaxmesh.mesh' not in sys.modules, sorted(sys.modules); "
            "jaxmesh.cli.build_parser(('info',)); assert 'jaxmesh.topology' in sys.modules; "
            "assert 'jaxmesh.denoise' not in sys.modules and 'jaxmesh.stats' not in sys.modules; "
            "import jaxmesh.view; assert all(getattr(jaxmesh, n) is not None for n in jaxmesh.__all__)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]


def test_every_command_module_is_named_in_the_table():
    from jaxmesh.cli import COMMANDS, build_parser

    modules = {p.stem for p in (ROOT / "cli").glob("*.py") if not p.stem.startswith("_")}
    assert modules == set(COMMANDS)
    import argparse

    parser = build_parser()            # every command's options and run function
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name in COMMANDS:
        assert sub.choices[name].get_default("_run") is importlib.import_module(f"jaxmesh.cli.{name}").run
    only = next(a for a in build_parser(("info",))._actions if isinstance(a, argparse._SubParsersAction))
    assert only.choices["info"].get_default("_run") is not None and only.choices["hash"].get_default("_run") is None

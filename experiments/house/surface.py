"""The size of the package's surface, for comparing two versions of it.

    .venv/bin/python experiments/house/surface.py [--root DIR]

Reads the ``jaxmesh`` package under ``--root`` (default: this checkout) and
prints: the public functions and constants (names in a public module's
``__all__``, private and command-line modules left out; a name re-exported by
a package counts once, where it is defined), the private modules, the imports
of a private name from another module, the longest modules and functions, and
how many function parameters carry an annotation.  Run it on two checkouts and
compare (``duplicates`` from the tool library gives the repeated-code pairs).
"""

from __future__ import annotations

import argparse
import ast
import importlib
import inspect
import pkgutil
import sys
from pathlib import Path


def _public(root: Path) -> tuple[int, int]:
    """(public functions, public constants), each function counted once where it is defined."""
    sys.path.insert(0, str(root))
    import jaxmesh

    names = ["jaxmesh"] + [m.name for m in pkgutil.walk_packages(jaxmesh.__path__, "jaxmesh.")
                           if "._" not in m.name and ".cli" not in m.name]
    functions, constants = set(), set()
    for name in names:
        module = importlib.import_module(name)
        for attr in getattr(module, "__all__", ()):
            obj = getattr(module, attr, None)
            if inspect.ismodule(obj) or inspect.isclass(obj):
                continue
            if callable(obj):
                functions.add((getattr(obj, "__module__", name), getattr(obj, "__qualname__", attr)))
            elif attr.isupper():
                constants.add(attr)                # a re-exported constant keeps its name
    return len(functions), len(constants)


def _sources(root: Path) -> dict[str, ast.Module]:
    return {str(p.relative_to(root)): ast.parse(p.read_text(), str(p))
            for p in sorted((root / "jaxmesh").rglob("*.py"))}


def _functions(tree: ast.Module):
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[2])
    args = ap.parse_args()
    root = args.root.resolve()
    sources = _sources(root)
    functions, constants = _public(root)
    private = [p for p in sources if Path(p).name.startswith("_") and Path(p).name != "__init__.py"
               and Path(p).name != "__main__.py"]
    imports = sum(1 for tree in sources.values() for node in ast.walk(tree)
                  if isinstance(node, ast.ImportFrom) and node.level > 0
                  for alias in node.names if alias.name.startswith("_") and not alias.name.startswith("__"))
    lines = {p: len((root / p).read_text().splitlines()) for p in sources}
    spans = sorted(((f.end_lineno - f.lineno + 1, f"{p}:{f.name}") for p, tree in sources.items()
                    for f in _functions(tree)), reverse=True)
    params = [a for tree in sources.values() for f in _functions(tree)
              for a in (*f.args.posonlyargs, *f.args.args, *f.args.kwonlyargs) if a.arg not in ("self", "cls")]
    print(f"package: {len(sources)} files, {sum(lines.values())} lines")
    print(f"public functions: {functions}; public constants: {constants}")
    print(f"private modules: {len(private)}")
    print(f"relative imports of a private name: {imports}")
    print("longest modules: " + ", ".join(f"{p} {n}" for p, n in sorted(lines.items(), key=lambda kv: -kv[1])[:5]))
    print("longest functions: " + ", ".join(f"{name} {n}" for n, name in spans[:5]))
    annotated = sum(a.annotation is not None for a in params)
    print(f"annotated parameters: {annotated} of {len(params)}")


if __name__ == "__main__":
    main()

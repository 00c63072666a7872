"""The API reference's raw material: every public function is documented with
structured Arguments/Returns sections (what mkdocstrings renders as tables) that name
exactly the function's parameters.  `mkdocs build --strict` itself runs in .ci/run."""

import importlib
import inspect
import pkgutil
import re
from pathlib import Path

import jaxmesh


def public_functions() -> dict:
    """Every function named in a public module's ``__all__`` (private and CLI modules
    left out), by its defining module and name."""
    names = ["jaxmesh"] + [m.name for m in pkgutil.walk_packages(jaxmesh.__path__, "jaxmesh.")
                           if "._" not in m.name and ".cli" not in m.name]
    out = {}
    for name in names:
        module = importlib.import_module(name)
        for attr in getattr(module, "__all__", []):
            obj = getattr(module, attr, None)
            if inspect.isfunction(obj):
                out[(obj.__module__, obj.__qualname__)] = obj
    return out


def _structured(doc: str) -> bool:
    return bool(re.search(r"^(Arguments|Args):\n", doc, re.M) and re.search(r"^Returns:\n", doc, re.M))


def test_every_public_function_has_a_docstring():
    functions = public_functions()
    assert len(functions) > 200
    missing = sorted(f"{m}.{q}" for (m, q), f in functions.items() if not inspect.getdoc(f))
    assert not missing, missing


def test_every_public_function_has_arguments_and_returns():
    functions = public_functions()
    for (module, name), f in sorted(functions.items()):
        fn = inspect.unwrap(f)
        doc = inspect.getdoc(fn)
        assert _structured(doc), f"{module}.{name} has no Arguments:/Returns: sections"
        documented = re.findall(r"^    (\*{0,2}\w+):", doc.split("\nReturns:")[0].split("\nArguments:")[1], re.M)
        params = [("**" if p.kind is p.VAR_KEYWORD else "") + p.name
                  for p in inspect.signature(fn).parameters.values()]
        assert documented == params, f"{module}.{name}: documented {documented}, takes {params}"
        returns = doc.split("\nReturns:\n")[1]
        assert returns.strip(), f"{module}.{name}: empty Returns section"


def rendered_functions() -> set:
    """The functions the API reference renders: every ``::: module`` directive of
    docs/api renders the module's ``__all__``, or only its ``members:`` option."""
    out = set()
    for page in (Path(__file__).parent.parent / "docs" / "api").glob("*.md"):
        for name, members in re.findall(r"^::: ([\w.]+)\n(?:    options:\n      members: \[([^\]]*)\])?",
                                         page.read_text(), re.M):
            module = importlib.import_module(name)
            names = [m.strip() for m in members.split(",")] if members else getattr(module, "__all__", [])
            out |= {id(getattr(module, n)) for n in names}
    return out


def test_the_api_reference_renders_every_public_function():
    rendered = rendered_functions()
    absent = sorted(f"{m}.{q}" for (m, q), f in public_functions().items() if id(f) not in rendered)
    assert not absent, f"not in any docs/api page: {absent}"

"""The API reference's raw material: every public function is documented, and the
entry points a newcomer calls first have structured Arguments/Returns sections
(what mkdocstrings renders as tables).  `mkdocs build --strict` itself runs in .ci/run."""

import importlib
import inspect
import pkgutil
import re

import jaxmesh

STRUCTURED = [   # the first calls of the getting-started page and the guides, and the core modules
    ("jaxmesh.io", "load"), ("jaxmesh.io", "save"), ("jaxmesh.noise", "add_noise"),
    ("jaxmesh.transforms", "normalize"), ("jaxmesh.denoise", "denoise"), ("jaxmesh.tune", "tune"),
    ("jaxmesh.tune", "choose_denoiser"), ("jaxmesh.compress", "compress"), ("jaxmesh.hash", "robust_hash"),
    ("jaxmesh.stats", "mesh_statistics"), ("jaxmesh.dataset", "denoise_files"), ("jaxmesh.view", "viewer_html"),
    ("jaxmesh.view", "write_viewer"), ("jaxmesh.view", "vertex_distances"),
    *[(module, name) for module in ("jaxmesh.vf", "jaxmesh.geometry", "jaxmesh.operators", "jaxmesh.metrics",
                                    "jaxmesh.sparse")
      for name in importlib.import_module(module).__all__
      if inspect.isfunction(getattr(importlib.import_module(module), name))],
]


DEPRECATED = {"jaxmesh.attacks"}   # an alias of jaxmesh.hash.attacks that warns on import


def public_functions() -> dict:
    """Every function named in a public module's ``__all__`` (private and CLI modules
    left out), by its defining module and name."""
    names = ["jaxmesh"] + [m.name for m in pkgutil.walk_packages(jaxmesh.__path__, "jaxmesh.")
                           if "._" not in m.name and ".cli" not in m.name and m.name not in DEPRECATED]
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


def test_entry_points_have_arguments_and_returns():
    for module, name in STRUCTURED:
        fn = inspect.unwrap(getattr(importlib.import_module(module), name))
        doc = inspect.getdoc(fn)
        assert _structured(doc), f"{module}.{name} has no Arguments:/Returns: sections"
        documented = set(re.findall(r"^    (\*{0,2}\w+):", doc.split("Returns:")[0], re.M))
        params = {("**" if p.kind is p.VAR_KEYWORD else "") + p.name
                  for p in inspect.signature(fn).parameters.values()}
        assert documented == params, f"{module}.{name}: documented {sorted(documented)}, takes {sorted(params)}"

"""The package's shape (docs/decisions.md, "Shape of the code"): data flows one way through the layers, no import
cycles, light imports stay light, and no module changes a user's matplotlib backend.

Layers, lowest first: the shared helpers (``_version``, ``_io``, ``_validation``, ``_format``, ``_lazy``, ``_interrupt``) < ``materials`` < ``fem`` <
``actuator`` < ``study`` < ``assess`` < ``paper`` < ``cli`` < ``__main__`` (the command's entry point). A module may import its own layer and the ones
below, never one above. Imports inside functions count too: a lazy import is still a dependency.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "hydrojam"
LAYERS = ["_version", "_io", "_validation", "_format", "_lazy", "_interrupt", "materials", "fem", "actuator", "study", "assess",
          "paper", "cli", "__main__"]
RANK = {"_version": 0, "_io": 0, "_validation": 0, "_format": 0, "_lazy": 0, "_interrupt": 0, "materials": 1, "fem": 2,
        "actuator": 3, "study": 4, "assess": 5, "paper": 6, "cli": 7, "__main__": 8}


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(SRC.rglob("*.py"))}


def _imports(name: str, path: Path) -> set[str]:
    """hydrojam modules that ``name`` imports anywhere in its source (relative ones resolved)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("hydrojam"))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if not mod.startswith("hydrojam"):
                continue
            found.add(mod)
            found.update(f"{mod}.{a.name}" for a in node.names)  # `from pkg import module`
    modules = _modules()
    return {m for m in found if m in modules and m != name}


def _layer(module: str) -> str | None:
    parts = module.split(".")
    return parts[1].removesuffix(".py") if len(parts) > 1 else None  # None: the package itself


def test_every_module_belongs_to_a_layer():
    for name in _modules():
        layer = _layer(name)
        assert layer is None or layer in RANK, f"{name}: not in a known layer {LAYERS}; add it to the layer list"


def test_no_module_imports_a_higher_layer():
    wrong = []
    for name, path in _modules().items():
        layer = _layer(name)
        if layer is None:  # hydrojam/__init__.py names the public API of every layer
            continue
        for dep in _imports(name, path):
            dep_layer = _layer(dep)
            if dep_layer is not None and RANK[dep_layer] > RANK[layer]:
                wrong.append(f"{name} ({layer}) imports {dep} ({dep_layer})")
    assert not wrong, "imports against the data flow:\n" + "\n".join(wrong)


def test_no_import_cycles():
    modules = _modules()
    graph = {name: _imports(name, path) - {"hydrojam"} for name, path in modules.items()}
    # a package's __init__ importing its own submodules is not a cycle of concepts
    for name in graph:
        graph[name] = {d for d in graph[name] if not d.startswith(name + ".")}
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def visit(node: str, stack: list[str]) -> None:
        state[node] = 1
        stack.append(node)
        for dep in sorted(graph.get(node, ())):
            if state.get(dep) == 1:
                cycles.append(stack[stack.index(dep):] + [dep])
            elif dep not in state:
                visit(dep, stack)
        stack.pop()
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node, [])
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def test_no_module_sets_the_matplotlib_backend_or_uses_pyplot():
    """A notebook user's backend must not change: figures are drawn on matplotlib.figure.Figure."""
    wrong = []
    for name, path in _modules().items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute) and node.attr == "use" and isinstance(node.value, ast.Name) \
                    and node.value.id == "matplotlib":
                wrong.append(f"{name}: matplotlib.use")
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names] + [getattr(node, "module", None) or ""]
                if any(n.startswith("matplotlib.pyplot") for n in names) or (
                        getattr(node, "module", None) == "matplotlib" and any(a.name == "pyplot" for a in node.names)):
                    wrong.append(f"{name}: imports pyplot")
    assert not wrong, "\n".join(wrong)


@pytest.mark.parametrize("code", [
    "import hydrojam",
    "from hydrojam import Design, Hydrogel, free_swelling",
    "from hydrojam.cli import main; main(['swell', '--temperatures', '275', '--json'])",
])
def test_light_entry_points_do_not_load_gmsh_or_ipctk(code):
    """``import hydrojam`` and ``hydrojam swell`` need neither gmsh (GL libraries) nor ipctk."""
    probe = f"import sys, contextlib, io\nwith contextlib.redirect_stdout(io.StringIO()):\n    {code}\n" \
            "print(sorted(m for m in ('gmsh', 'ipctk', 'pypardiso', 'dask', 'matplotlib.pyplot') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "[]", out.stdout + out.stderr


def test_layout_names_every_module():
    """The API reference's layout section (docs/api/index.md) matches the tree: every module and subpackage is named there,
    and every ``*.py`` named there exists."""
    import re

    page = (SRC.parents[1] / "docs" / "api" / "index.md").read_text()
    block = page.split("## Layout", 1)[1].split("```", 2)[1]
    named = set(re.findall(r"\b(\w+\.py)\b", block))
    files = {p.name for p in SRC.rglob("*.py") if p.name != "__init__.py"} | {"__init__.py"}
    missing = sorted(files - named)
    assert not missing, f"modules missing from docs/api/index.md's layout section: {missing}"
    extra = sorted(named - files)
    assert not extra, f"docs/api/index.md's layout section names modules that do not exist: {extra}"
    packages = {p.parent.name for p in SRC.rglob("__init__.py") if p.parent != SRC}
    assert all(f"{pkg}/" in block for pkg in packages), f"subpackages missing: {packages}"


def test_the_version_is_defined_once_and_matches_the_package_metadata():
    """``hydrojam.__version__`` is ``hydrojam._version``'s, and pyproject.toml states the same."""
    import tomllib

    import hydrojam
    from hydrojam._version import __version__

    pyproject = tomllib.loads((SRC.parents[1] / "pyproject.toml").read_text())
    assert hydrojam.__version__ == __version__ == pyproject["project"]["version"]


def _public_names(package: str) -> set[str] | None:
    """The names a subpackage's ``__init__`` makes public (its ``__all__``, or the lists of its lazy
    ``_PUBLIC``), read from its source; None where ``package`` is not a subpackage."""
    path = _modules().get(package)
    if path is None or path.name != "__init__.py":
        return None
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id in ("_PUBLIC", "__all__")
                                                for t in node.targets):
            lists = node.value.values if isinstance(node.value, ast.Dict) else [node.value]
            names |= {e.value for v in lists if isinstance(v, (ast.List, ast.Tuple)) for e in v.elts}
    return names


def _imported_names(name: str, path: Path):
    """(module, name) of every ``from hydrojam... import name`` in ``name``'s source."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                mod = ".".join(base[: len(base) - node.level + 1] + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.startswith("hydrojam"):
                yield from ((mod, a.name) for a in node.names)


def test_imports_across_subpackages_use_only_their_public_names():
    """The faces are the boundary: a module imports from another subpackage (fem, actuator, ...)
    only the names that subpackage's ``__init__`` makes public."""
    wrong = []
    for name, path in _modules().items():
        layer = _layer(name)
        for mod, imported in _imported_names(name, path):
            other = _layer(mod)
            if layer is None or other is None or other == layer or RANK[other] == 0:
                continue  # the same subpackage, or the shared helpers (_io, _validation, ...)
            public = _public_names(f"hydrojam.{other}")
            if public is None:
                continue  # a layer that is one module (cli): its names are its own
            if f"{mod}.{imported}" in _modules():
                wrong.append(f"{name}: imports the module {mod}.{imported}")
            elif imported not in public:
                wrong.append(f"{name}: from {mod} import {imported} (not in hydrojam.{other}'s public names)")
    assert not wrong, "imports across subpackages past their faces:\n" + "\n".join(wrong)


def test_no_private_name_is_imported_from_another_module():
    """A private name (``_name``) stays in its module; a private module (``_kernels``) is imported
    only within its own package."""
    wrong = []
    for name, path in _modules().items():
        for mod, imported in _imported_names(name, path):
            if not imported.startswith("_") or imported.startswith("__"):
                continue
            if f"{mod}.{imported}" in _modules():
                if not (name + ".").startswith(mod + "."):
                    wrong.append(f"{name}: imports the private module {mod}.{imported}")
            else:
                wrong.append(f"{name}: from {mod} import {imported}")
    assert not wrong, "private names imported from other modules:\n" + "\n".join(wrong)

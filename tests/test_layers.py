"""The package's shape, enforced: imports only down the data flow, no import cycle, no
private name taken from another module, imports at the top of files.

Layers, lowest first: errors (and the package root) -> jsonfile -> camera | files -> scene -> sort ->
render -> capture -> viewer | bench -> cli. A module may import its own subpackage
and any lower layer; camera and files, and viewer and bench, stand side by side and
import neither each other.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "raygs_viewer"
LAYERS = {"errors": 0, "jsonfile": 1, "camera": 2, "files": 2, "scene": 3, "sort": 4, "render": 5, "capture": 6, "photos": 6.5, "viewer": 7,
          "bench": 7, "cli": 8, "__main__": 9}


def modules_of(package: Path) -> dict[str, Path]:
    """{dotted module name: file} of every module under ``package``."""
    modules = {}
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(parts)] = path
    return modules


def layer(module: str) -> tuple[str, int]:
    parts = module.split(".")
    if len(parts) == 1:  # the package root (__version__)
        return parts[0], 0
    return parts[1], LAYERS[parts[1]]


def imports(path: Path, modules: dict[str, Path]):
    """(node, imported module, names taken from it) of each import of the package."""
    root = next(iter(modules)).split(".")[0]
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == root:
                    yield node, alias.name, []
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == root:
            names = [a.name for a in node.names]
            submodules = [n for n in names if f"{node.module}.{n}" in modules]
            for name in submodules:
                yield node, f"{node.module}.{name}", []
            yield node, node.module, [n for n in names if n not in submodules]


def upward_imports(modules: dict[str, Path]) -> list[str]:
    wrong = []
    for module, path in modules.items():
        name, level = layer(module)
        for node, target, _ in imports(path, modules):
            target_name, target_level = layer(target)
            if target_name != name and target_level >= level:
                wrong.append(f"{path.name}:{node.lineno} {module} -> {target}")
    return wrong


def import_cycles(modules: dict[str, Path]) -> list[list[str]]:
    graph = {module: {target for _, target, _ in imports(path, modules) if target in modules and target != module}
             for module, path in modules.items()}
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(node: str) -> None:  # Tarjan's strongly connected components
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in graph[node]:
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for node in graph:
        if node not in index:
            visit(node)
    return cycles


def private_imports(modules: dict[str, Path]) -> list[str]:
    taken = []
    for module, path in modules.items():
        for node, target, names in imports(path, modules):
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            if private and target != module:
                taken.append(f"{path.name}:{node.lineno} {private} from {target}")
    return taken


def silent_late_imports(modules: dict[str, Path]) -> list[str]:
    """Imports inside functions with no comment on their line or the line above."""
    silent = []
    for path in modules.values():
        lines = path.read_text().splitlines()
        tree = ast.parse("\n".join(lines))
        top = {id(node) for node in tree.body}
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) not in top:
                here, above = lines[node.lineno - 1], lines[node.lineno - 2] if node.lineno > 1 else ""
                if "#" not in here and not above.strip().startswith("#"):
                    silent.append(f"{path.name}:{node.lineno}: {here.strip()}")
    return silent


MODULES = modules_of(PACKAGE)


def test_every_module_has_a_layer():
    for module in MODULES:
        layer(module)  # KeyError for a subpackage missing from LAYERS


def test_imports_go_down_the_layers():
    wrong = upward_imports(MODULES)
    assert not wrong, "imports against the layer order:\n" + "\n".join(wrong)


def test_no_import_cycles():
    cycles = import_cycles(MODULES)
    assert not cycles, f"import cycles: {cycles}"


def test_no_private_names_from_other_modules():
    taken = private_imports(MODULES)
    assert not taken, "private names imported from other modules:\n" + "\n".join(taken)


def test_late_imports_say_why():
    silent = silent_late_imports(MODULES)
    assert not silent, "imports inside functions without a comment saying why:\n" + "\n".join(silent)


def test_the_checks_see_what_they_forbid(tmp_path):
    """The control: a small package with one of each fault, and each check finds its own."""
    package = tmp_path / "pkg"
    files = {
        "camera/__init__.py": "",
        "camera/pinhole.py": "from pkg.viewer.app import Viewer\n",  # upward
        "scene/__init__.py": "",
        "scene/a.py": "from pkg.scene.b import _helper\n",  # private, and a cycle with b
        "scene/b.py": "import pkg.scene.a\n\ndef _helper():\n    import json\n",  # silent late import
        "viewer/__init__.py": "",
        "viewer/app.py": "from pkg.scene import a\n\nclass Viewer:\n    pass\n",
    }
    for name, text in files.items():
        (package / name).parent.mkdir(parents=True, exist_ok=True)
        (package / name).write_text(text)
    modules = modules_of(package)
    assert upward_imports(modules) == ["pinhole.py:1 pkg.camera.pinhole -> pkg.viewer.app"]
    assert import_cycles(modules) == [["pkg.scene.a", "pkg.scene.b"]]
    assert private_imports(modules) == ["a.py:1 ['_helper'] from pkg.scene.b"]
    assert silent_late_imports(modules) == ["b.py:4: import json"]


def test_every_subpackage_is_installed():
    """pyproject.toml lists the packages by name: a new subpackage missing there would
    pass the tests in a checkout and be absent from an installed copy."""
    tomllib = pytest.importorskip("tomllib")
    listed = set(tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    present = {".".join(init.parent.relative_to(PACKAGE.parent).parts) for init in PACKAGE.rglob("__init__.py")}
    assert present <= listed, f"subpackages missing from pyproject.toml: {sorted(present - listed)}"

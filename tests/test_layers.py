"""The package's shape, enforced: imports only down the data flow, no import cycle, no
private name taken from another module, imports at the top of files.

Layers, lowest first: errors (and the package root) -> camera -> scene -> sort ->
render -> capture -> viewer | bench -> cli. A module may import its own subpackage
and any lower layer; viewer and bench stand side by side and import neither each other.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "raygs_viewer"
LAYERS = {"errors": 0, "camera": 1, "scene": 2, "sort": 3, "render": 4, "capture": 5, "viewer": 6, "bench": 6,
          "cli": 7, "__main__": 8}
#: Function-level imports are allowed where a comment on the line, or the line above,
#: says why (a heavy optional dependency).


def _modules() -> dict[str, Path]:
    modules = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        modules[".".join(parts)] = path
    return modules


MODULES = _modules()


def _layer(module: str) -> tuple[str, int]:
    parts = module.split(".")
    if len(parts) == 1:  # the package root (__version__)
        return "raygs_viewer", 0
    return parts[1], LAYERS[parts[1]]


def _imports(path: Path):
    """(line, imported module, names taken from it, at top level?) of each raygs_viewer import."""
    tree = ast.parse(path.read_text(), str(path))
    top = {id(node) for node in tree.body}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "raygs_viewer":
                    yield node, alias.name, [], id(node) in top
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "raygs_viewer":
            names = [a.name for a in node.names]
            submodules = [n for n in names if f"{node.module}.{n}" in MODULES]
            for name in submodules:
                yield node, f"{node.module}.{name}", [], id(node) in top
            yield node, node.module, [n for n in names if n not in submodules], id(node) in top


def _graph() -> dict[str, set[str]]:
    graph = {}
    for module, path in MODULES.items():
        graph[module] = {target for _, target, _, _ in _imports(path) if target in MODULES and target != module}
    return graph


def test_every_module_has_a_layer():
    for module in MODULES:
        assert _layer(module)[0] in LAYERS or module == "raygs_viewer", module


def test_imports_go_down_the_layers():
    wrong = []
    for module, path in MODULES.items():
        name, layer = _layer(module)
        for node, target, _, _ in _imports(path):
            target_name, target_layer = _layer(target)
            if target_name == name:
                continue
            if target_layer >= layer:
                wrong.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno} {module} -> {target}")
    assert not wrong, "imports against the layer order:\n" + "\n".join(wrong)


def test_no_import_cycles():
    graph = _graph()
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
    assert not cycles, f"import cycles: {cycles}"


def test_no_private_names_from_other_modules():
    taken = []
    for module, path in MODULES.items():
        for node, target, names, _ in _imports(path):
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            if private and target != module:
                taken.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno} {private} from {target}")
    assert not taken, "private names imported from other modules:\n" + "\n".join(taken)


def test_late_imports_say_why():
    silent = []
    for module, path in MODULES.items():
        lines = path.read_text().splitlines()
        tree = ast.parse("\n".join(lines))
        top = {id(node) for node in tree.body}
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) not in top:
                here, above = lines[node.lineno - 1], lines[node.lineno - 2] if node.lineno > 1 else ""
                if "#" not in here and not above.strip().startswith("#"):
                    silent.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno}: {here.strip()}")
    assert not silent, "imports inside functions without a comment saying why:\n" + "\n".join(silent)


@pytest.mark.parametrize("bad", ["raygs_viewer.viewer.app", "raygs_viewer.cli.main"])
def test_the_layer_check_sees_an_upward_import(bad, tmp_path):
    """The control: the rule above would catch camera importing a higher layer."""
    assert _layer(bad)[1] > _layer("raygs_viewer.camera.pinhole")[1]

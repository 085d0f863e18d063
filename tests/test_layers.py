"""The package's shape, enforced: imports only down the data flow, no import cycle, no
private name taken from another module, imports at the top of files, no code written twice,
no function taking more than five positional parameters.

Layers, lowest first: errors (and the package root) -> jsonfile -> camera | files -> scene -> sort ->
render -> capture -> photos -> viewer | bench -> cli -> __main__. A module may import its own
subpackage and any lower layer; camera and files, and viewer and bench, stand side by side
and import neither each other. The order has one home, ``LAYER_GROUPS`` in
docs/architecture_table.py, which draws it as the diagram of docs/architecture.md.
"""

from __future__ import annotations

import ast
import io
import sys
import tokenize
from collections import defaultdict
from pathlib import Path

import pytest

# The layer order and the walk over the package live with the script that draws the
# architecture's diagram from them, so the diagram and this test cannot disagree.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs"))
from architecture_table import INDENTED_IMPORT, LAYERS, late_imports, layer_of, modules_of, parsed  # noqa: E402

PACKAGE = Path(__file__).resolve().parents[1] / "raygs_viewer"


def imports(path: Path, modules: dict[str, Path]):
    """(node, imported module, names taken from it) of each import of the package."""
    root = next(iter(modules)).split(".")[0]
    text = path.read_text()
    tree = parsed(text, str(path))
    # Only a module with an indented import line has imports below its top level to walk to.
    for node in ast.walk(tree) if INDENTED_IMPORT.search(text) else tree.body:
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


def upward_imports(modules: dict[str, Path], layers: dict[str, int] = LAYERS) -> list[str]:
    """'file:line module -> target' of each import of a layer above, or beside, the
    importing module's (``layers``: {top-level module or package: its place})."""
    wrong = []
    for module, path in modules.items():
        name, level = layer_of(module, layers)
        for node, target, _ in imports(path, modules):
            target_name, target_level = layer_of(target, layers)
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
    return [f"{late.path.name}:{late.line}: {late.text}" for late in late_imports(modules) if not late.says_why]


#: The most positional parameters a function takes, ``self`` and ``cls`` not counted.
MOST_POSITIONALS = 5


def long_signatures(modules: dict[str, Path]) -> list[str]:
    """'module:line name takes N positionals' of each function, method or lambda with
    more than MOST_POSITIONALS positional parameters: past the first few, a call reads
    only with the signature beside it and two arguments swap silently, so the rest are
    keyword-only (or, when they travel together, one value)."""
    long = []
    for module, path in modules.items():
        for node in ast.walk(parsed(path.read_text(), str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                names = [a.arg for a in node.args.posonlyargs + node.args.args]
                count = len(names) - (names[:1] in (["self"], ["cls"]))
                if count > MOST_POSITIONALS:
                    long.append(f"{module}:{node.lineno} {getattr(node, 'name', 'lambda')} takes {count} positionals")
    return long


#: How many lines in a row, written twice, make a repeat (the ``duplicates`` tool's own limit).
REPEAT_LINES = 6
_LAYOUT = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT, tokenize.ENDMARKER}


def code_lines(text: str) -> list[tuple[int, str]]:
    """(line number, shape) of each line of code. A shape keeps keywords, names and
    operators and blanks out strings and numbers, so the same code with other constants
    still matches; lines of only strings and punctuation (docstrings, help prose, tables
    of text) are data, not code, and are left out, as are comments and blank lines."""
    tokens = defaultdict(list)
    in_import = starts_statement = True
    for token in tokenize.generate_tokens(io.StringIO(text).readline):
        if token.type in (tokenize.NEWLINE, tokenize.ENDMARKER):
            in_import, starts_statement = False, True
            continue
        if token.type in _LAYOUT:
            continue
        if starts_statement:
            # Imports name what a module uses; two modules using the same things is not a repeat.
            in_import, starts_statement = token.string in ("import", "from"), False
        if not in_import:
            tokens[token.start[0]].append(token)
    shapes = []
    for number, line in sorted(tokens.items()):
        if all(t.type in (tokenize.STRING, tokenize.OP) for t in line):
            continue
        shapes.append((number, " ".join("'s'" if t.type == tokenize.STRING else "0" if t.type == tokenize.NUMBER
                                        else t.string for t in line)))
    return shapes


def repeated_runs(files: dict[str, str], run: int = REPEAT_LINES) -> list[str]:
    """'a.py:FIRST-LAST ~ b.py:FIRST' for each stretch of ``run`` or more lines of code
    that appears twice, in two files or twice in one. A window made of fewer than three
    different lines (a column of like assignments) is a table, not logic, and is skipped."""
    lines = {name: code_lines(text) for name, text in files.items()}
    places = defaultdict(list)
    for name, shapes in lines.items():
        for start in range(len(shapes) - run + 1):
            window = tuple(shape for _, shape in shapes[start:start + run])
            if len(set(window)) >= 3:
                places[window].append((name, start))
    # Each matching window pair, grouped by (file, file, offset) so that a long repeat reads as one run.
    pairs = defaultdict(set)
    for found in places.values():
        for i, (a, start_a) in enumerate(found):
            for b, start_b in found[i + 1:]:
                if a != b or abs(start_a - start_b) >= run:
                    pairs[(a, b, start_a - start_b)].add(start_a)
    runs = []
    for (a, b, offset), starts in sorted(pairs.items()):
        for start in sorted(starts):
            if start - 1 not in starts:
                end = start
                while end + 1 in starts:
                    end += 1
                runs.append(f"{a}:{lines[a][start][0]}-{lines[a][end + run - 1][0]} ~ {b}:{lines[b][start - offset][0]}")
    return runs


MODULES = modules_of(PACKAGE)


def test_every_module_has_a_layer():
    for module in MODULES:
        layer_of(module, LAYERS)  # KeyError for a subpackage missing from LAYERS


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


def test_no_function_takes_more_than_five_positionals():
    long = long_signatures(MODULES)
    assert not long, ("functions with more than five positional parameters (make the rest keyword-only):\n"
                      + "\n".join(long))


def test_no_code_is_written_twice():
    """One home for each piece of logic: a repeat of six lines or more, in one module or
    two, is a helper waiting to be written (or a table that wants to be data)."""
    files = {str(path.relative_to(PACKAGE)): path.read_text() for path in MODULES.values()}
    repeats = repeated_runs(files)
    assert not repeats, "code written twice (give it one home):\n" + "\n".join(repeats)


def test_the_repeat_check_sees_a_repeat_and_only_a_repeat():
    """The control: the same six lines with other constants are found, in two files and in
    one; the same lines with one statement changed, docstrings, and a column of like
    assignments are not."""
    body = ("def {name}(path, size):\n"
            "    data = load(path)\n"
            "    if data.size > {limit}:\n"
            "        raise ValueError('too big: ' + path)\n"
            "    image = data.reshape(size, size)\n"
            "    return image.astype(float) / {scale}\n")
    first = body.format(name="read_a", limit=10, scale=255)
    assert repeated_runs({"a.py": first, "b.py": body.format(name="read_a", limit=99, scale=65535)}) == [
        "a.py:1-6 ~ b.py:1"]
    assert repeated_runs({"a.py": first + "\n\nx = 1\n\n" + body.format(name="read_a", limit=3, scale=1)}) == [
        "a.py:1-6 ~ a.py:11"]
    changed = body.format(name="read_a", limit=10, scale=255).replace("astype(float)", "clip(0, 1)")
    assert repeated_runs({"a.py": first, "b.py": changed}) == []
    prose = '"""' + "\n".join(["words here"] * 8) + '"""\n'
    column = "".join(f"table[{n}] = '{letter}'\n" for n, letter in enumerate("abcdefgh"))
    assert repeated_runs({"a.py": prose + column, "b.py": prose + column.replace("= ", "= 1")}) == []


def test_the_checks_see_what_they_forbid(tmp_path):
    """The control: a small package with one of each fault, and each check finds its own
    (and not the method whose sixth parameter past ``self`` is keyword-only)."""
    package = tmp_path / "pkg"
    files = {
        "camera/__init__.py": "",
        "camera/pinhole.py": "from pkg.viewer.app import Viewer\n",  # upward
        "scene/__init__.py": "",
        "scene/a.py": "from pkg.scene.b import _helper\n",  # private, and a cycle with b
        "scene/b.py": "import pkg.scene.a\n\ndef _helper():\n    import json\n",  # silent late import
        "viewer/__init__.py": "",
        "viewer/app.py": ("from pkg.scene import a\n\nclass Viewer:\n"
                          "    def draw(self, a, b, c, d, e, *, f):\n        pass\n\n\n"
                          "def fly(a, b, c, d, e, f=1):\n    pass\n"),  # five positionals past self, and six
    }
    for name, text in files.items():
        (package / name).parent.mkdir(parents=True, exist_ok=True)
        (package / name).write_text(text)
    modules = modules_of(package)
    assert upward_imports(modules) == ["pinhole.py:1 pkg.camera.pinhole -> pkg.viewer.app"]
    assert import_cycles(modules) == [["pkg.scene.a", "pkg.scene.b"]]
    assert private_imports(modules) == ["a.py:1 ['_helper'] from pkg.scene.b"]
    assert silent_late_imports(modules) == ["b.py:4: import json"]
    assert long_signatures(modules) == ["pkg.viewer.app:8 fly takes 6 positionals"]


def test_every_subpackage_is_installed():
    """pyproject.toml lists the packages by name: a new subpackage missing there would
    pass the tests in a checkout and be absent from an installed copy."""
    tomllib = pytest.importorskip("tomllib")
    listed = set(tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    present = {".".join(init.parent.relative_to(PACKAGE.parent).parts) for init in PACKAGE.rglob("__init__.py")}
    assert present <= listed, f"subpackages missing from pyproject.toml: {sorted(present - listed)}"

"""docs/architecture.md against the code: one row per module and none for a module that
is gone, the generated parts (the diagram, the module table) as the package would
generate them now, and no import the diagram, as drawn, does not allow.

The generated parts come from docs/architecture_table.py; when these tests fail, run
``python docs/architecture_table.py`` and commit docs/architecture.md with the change.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

# The script that writes the generated parts is the one reading of the package that the
# document and these tests share.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs"))
import architecture_table as table  # noqa: E402
from test_layers import upward_imports  # noqa: E402

MODULES = table.modules_of(table.PACKAGE)
REGENERATE = "run `python docs/architecture_table.py` and commit docs/architecture.md"


def table_rows(document: str) -> list[str]:
    """The module named by each row of the document's module table, in order."""
    return re.findall(r"^\| `([^`]+)` \|", table.part_text(document, "modules"), re.M)


def row_problems(document: str, package: Path) -> list[str]:
    """Each module of ``package`` that has no row (an empty ``__init__`` needs none), each
    row whose module is gone, and each module with more than one row."""
    rows = table_rows(document)
    modules = table.modules_of(package)
    wanted = [table.short_name(m) for m, path in modules.items() if table.parsed(path.read_text(), str(path)).body]
    return ([f"no row for {name}" for name in wanted if name not in rows]
            + [f"a row for {name}, whose module is gone" for name in dict.fromkeys(rows) if name not in wanted]
            + [f"{rows.count(name)} rows for {name}" for name in dict.fromkeys(rows) if rows.count(name) > 1])


def drawn_layers(document: str) -> dict[str, int]:
    """{top-level module or package: its group, lowest first} as the document's diagram
    draws them: a line of only an arrow starts the next group; a line whose name starts
    in the second column draws a package (``render/gl/`` belongs to ``render``)."""
    block = table.part_text(document, "layers").split("```")
    assert len(block) >= 3, "the layers part holds no diagram"
    layers, group = {}, 0
    for line in block[1].strip("\n").splitlines():
        if line.strip() == table.ARROW:
            group += 1
        elif line[:1] == " " and line[1:2].strip():
            layers.setdefault(line.split()[0].split("/")[0], group)
    return layers


def defined_names(tree: ast.AST) -> set[str]:
    """The names a module (or a class body) defines or imports at its top level, and
    the methods and properties of a class."""
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names |= {(alias.asname or alias.name).split(".")[0] for alias in node.names}
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
        names |= {target.id for target in targets if isinstance(target, ast.Name)}
    return names


def unknown_names(document: str, package: Path) -> list[str]:
    """Each name the hand-written prose of ``document`` gives under a package's layer
    (``render.sorting.exact_order``, ``viewer.frame.Frame.make``) that the code lacks: no
    such module, no such top-level name in it, or no such member of a class."""
    for name in ("layers", "modules"):
        document = document.replace(table.part_text(document, name), "")
    modules = {table.short_name(m): path for m, path in table.modules_of(package).items() if "." in m}
    tops = "|".join(sorted({module.split(".")[0] for module in modules}))
    unknown = []
    for name in sorted(set(re.findall(rf"\b(?<![./])((?:{tops})(?:\.[A-Za-z_]\w*)+)", document))):
        parts = name.split(".")
        owner = next((i for i in range(len(parts), 0, -1) if ".".join(parts[:i]) in modules), None)
        if owner is None or name.endswith(".py"):
            unknown += [] if name.endswith(".py") else [f"{name}: no module {'.'.join(parts[:2])}"]
            continue
        module, rest = ".".join(parts[:owner]), parts[owner:]
        tree = table.parsed(modules[module].read_text(), str(modules[module]))
        if rest and rest[0] not in defined_names(tree):
            unknown.append(f"{name}: {module} has no {rest[0]}")
        elif len(rest) > 1:
            classes = [node for node in tree.body if isinstance(node, ast.ClassDef) and node.name == rest[0]]
            if classes and rest[1] not in defined_names(classes[0]):
                unknown.append(f"{name}: {rest[0]} has no {rest[1]}")
    return unknown


def test_every_module_has_one_row_and_no_row_outlives_its_module():
    problems = row_problems(table.DOCUMENT.read_text(), table.PACKAGE)
    assert not problems, f"docs/architecture.md's module table disagrees with the package ({REGENERATE}):\n" + \
        "\n".join(problems)


def test_the_generated_parts_are_what_the_code_generates_now():
    diff = table.staleness(table.DOCUMENT.read_text(), table.PACKAGE)
    assert not diff, f"docs/architecture.md is stale ({REGENERATE}):\n{diff}"


def test_the_diagram_draws_every_package_in_the_order_the_layer_test_enforces():
    drawn = drawn_layers(table.DOCUMENT.read_text())
    assert drawn == table.LAYERS
    assert {module.split(".")[1] for module in MODULES if "." in module} <= set(drawn)


def test_every_import_goes_down_the_diagram_as_drawn():
    wrong = upward_imports(MODULES, drawn_layers(table.DOCUMENT.read_text()))
    assert not wrong, "imports the diagram of docs/architecture.md does not allow:\n" + "\n".join(wrong)


def test_the_prose_names_only_what_the_code_has():
    """The hand-written parts (the path of a frame, where a change goes, the shader
    table...) name modules, functions and methods; a rename must take them along."""
    unknown = unknown_names(table.DOCUMENT.read_text(), table.PACKAGE)
    assert not unknown, "docs/architecture.md names what the code no longer has:\n" + "\n".join(unknown)


def test_the_checks_see_a_missing_row_a_gone_row_a_stale_row_and_an_arrow_not_drawn(tmp_path, capsys):
    """The control: a small package and its document, fresh, then one fault at a time."""
    package = tmp_path / "pkg"
    files = {"__init__.py": "", "scene/__init__.py": "", "render/__init__.py": "",
             "scene/a.py": '"""Low things."""\n\n\ndef thing():\n    pass\n',
             "render/b.py": '"""High things:\n\n- one;\n- two.\n"""\nfrom pkg.scene.a import thing\n\n__all__ = ["thing"]\n'}
    for name, text in files.items():
        (package / name).parent.mkdir(parents=True, exist_ok=True)
        (package / name).write_text(text)
    groups = (("scene",), ("render",))
    markers = "\n\n".join(f"{table.BEGIN.format(name=n)}\n{table.END.format(name=n)}" for n in ("layers", "modules"))
    document = table.with_parts(f"# Made up\n\n{markers}\n\nProse.\n", table.generated_parts(package, groups))
    assert table_rows(document) == ["scene.a", "render.b"]
    assert "| `render.b` | High things: one; two. | `thing` |" in document
    assert drawn_layers(document) == {"scene": 0, "render": 1}
    assert table.staleness(document, package, groups) == ""
    assert row_problems(document, package) == []
    assert upward_imports(table.modules_of(package), drawn_layers(document)) == []

    (package / "scene/a.py").write_text('"""Low things, renamed."""\n\n\ndef thing():\n    pass\n')
    diff = table.staleness(document, package, groups)
    assert "-| `scene.a` | Low things. | `thing` |" in diff and "+| `scene.a` | Low things, renamed. | `thing` |" in diff

    (package / "scene/c.py").write_text('"""More."""\n')
    (package / "render/b.py").unlink()
    assert row_problems(document, package) == ["no row for scene.c", "a row for render.b, whose module is gone"]
    assert row_problems(document.replace("| `scene.a` |", "| `scene.a` | twice |\n| `scene.a` |"), package) == [
        "no row for scene.c", "a row for render.b, whose module is gone", "2 rows for scene.a"]

    (package / "render/b.py").write_text('"""High things."""\n')
    (package / "scene/a.py").write_text('"""Low things."""\nimport pkg.render.b\n')
    assert upward_imports(table.modules_of(package), drawn_layers(document)) == ["a.py:2 pkg.scene.a -> pkg.render.b"]
    swapped = table.with_parts(document, {"layers": table.generated_parts(package, groups[::-1])["layers"]})
    assert drawn_layers(swapped) == {"render": 0, "scene": 1}
    assert upward_imports(table.modules_of(package), drawn_layers(swapped)) == []

    prose = document + "\n`scene.a.thing`, `render.b`, render.b.gone, `scene.gone`, `render.b.Thing.run`, scene/a.py\n"
    (package / "render/b.py").write_text('"""High things."""\n\n\nclass Thing:\n    size: int\n\n    def go(self):\n        pass\n')
    assert unknown_names(prose, package) == ["render.b.Thing.run: Thing has no run", "render.b.gone: render.b has no gone",
                                             "scene.a.thing: scene.a has no thing", "scene.gone: scene has no gone"]
    assert unknown_names(prose.replace(".run", ".go").replace("scene.a.thing", "scene.a")
                         .replace(", render.b.gone, `scene.gone`", ""), package) == []

    # The script itself: --check changes nothing and says what is stale; a rewrite makes it fresh.
    written = tmp_path / "made_up.md"
    written.write_text(document)
    argv = ["--document", str(written), "--package", str(package)]
    assert table.main(argv + ["--check"]) == 1 and written.read_text() == document
    assert "+| `scene.c` | More. | (none) |" in capsys.readouterr().err
    assert table.main(argv) == 0 and table.main(argv + ["--check"]) == 0
    written.write_text("# No markers\n")
    assert table.main(argv) == 2 and "no markers for the part 'layers'" in capsys.readouterr().err

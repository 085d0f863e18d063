"""The window's parts keep only their own state (viewer.part): no part holds the viewer or
another part, the panel's lines change only through ``PanelState.say``, and the frame
statistics are written only in viewer/stats.py, from the drawer's report."""

from __future__ import annotations

import ast
import functools
import types
from pathlib import Path

import numpy as np
import pytest

from raygs_viewer.viewer.drawing import DrawReport
from raygs_viewer.viewer.part import Reply
from raygs_viewer.viewer.state import Message, PanelState, done, failed, mended, note
from raygs_viewer.viewer.stats import FrameStats

VIEWER = Path(__file__).resolve().parents[2] / "raygs_viewer"


def parts_of(viewer) -> dict[str, object]:
    """The parts issue 52 names, by name: each must hold neither the viewer nor another."""
    return {"path": viewer.camera_path, "measure": viewer.measure, "pick": viewer.picker, "edit": viewer.edit_tool,
            "level of detail": viewer.scene.lod, "photo view": viewer.photo, "frustums": viewer.frustums,
            "statistics": viewer.stats, "screenshots": viewer.captures, "stereo": viewer.stereo}


def held(obj, targets: dict[int, str], depth: int = 4, path: str = "", seen: set | None = None) -> list[str]:
    """Where ``obj`` holds one of ``targets`` ({id: name}), as attribute paths: looking
    through the project's objects' attributes, containers, bound methods, partials and
    closures, ``depth`` steps deep (GL, imgui and numpy objects are leaves)."""
    seen = set() if seen is None else seen
    if depth < 0 or id(obj) in seen or isinstance(obj, (str, bytes, int, float, bool, np.ndarray, type(None))):
        return []
    seen.add(id(obj))
    if path and id(obj) in targets:
        return [f"{path} is the {targets[id(obj)]}"]
    if isinstance(obj, dict):
        children = [(f"[{key!r}]", value) for key, value in obj.items()]
    elif isinstance(obj, (list, tuple, set, frozenset)):
        children = [(f"[{i}]", value) for i, value in enumerate(obj)]
    elif isinstance(obj, types.MethodType):
        children = [(".__self__", obj.__self__)]
    elif isinstance(obj, functools.partial):
        children = [(".func", obj.func), (".args", obj.args), (".keywords", obj.keywords)]
    elif isinstance(obj, types.FunctionType):
        children = [(f".<closure {i}>", cell.cell_contents) for i, cell in enumerate(obj.__closure__ or ())]
    elif type(obj).__module__.startswith("raygs_viewer") and hasattr(obj, "__dict__"):
        children = [(f".{name}", value) for name, value in vars(obj).items()]
    else:
        return []
    return [found for step, child in children for found in held(child, targets, depth - 1, path + step, seen)]


def test_no_part_holds_the_viewer_or_another_part(open_viewer, tmp_path):
    viewer, drive = open_viewer(width=400, height=300)  # the panel drawn: every section's wiring ran
    drive.frames(3)
    parts = parts_of(viewer)
    for name, part in parts.items():
        targets = {id(viewer): "viewer", **{id(other): f"{other_name} part" for other_name, other in parts.items()
                                            if other is not part}}
        assert held(part, targets) == [], name
    # The edit tool's export and handles hold no edit tool either.
    for name, piece in (("export", viewer.edit_tool.exporter), ("handles", viewer.edit_tool.handles)):
        assert held(piece, {id(viewer.edit_tool): "edit tool", id(viewer): "viewer"}) == [], name

    # The control: a back-reference planted anywhere the walk looks is found.
    viewer.edit_tool.handles.owner = viewer
    viewer.camera_path.callbacks = [lambda: viewer.measure]
    try:
        others = {id(viewer): "viewer", id(viewer.measure): "measure part"}
        assert held(viewer.edit_tool, others) == [".handles.owner is the viewer"]
        assert held(viewer.camera_path, others) == [".callbacks[0].<closure 0> is the viewer"]
    finally:
        del viewer.edit_tool.handles.owner, viewer.camera_path.callbacks


def test_the_panel_lines_change_only_through_say():
    panel = PanelState()
    with pytest.raises(AttributeError):
        panel.message = "assigned"
    with pytest.raises(AttributeError):
        panel.error = "assigned"
    panel.say(note("one"), failed("went wrong", "saved"))
    assert (panel.message, panel.error) == ("one", "error: saved: went wrong")
    panel.say(note("two"))  # a note leaves the error up
    assert (panel.message, panel.error) == ("two", "error: saved: went wrong")
    panel.say(done("three"))  # an action that went well clears it
    assert (panel.message, panel.error) == ("three", "")
    panel.say(failed("no headset", source="stereo"))
    panel.say(mended("view"))  # another source's mend leaves it
    assert panel.error == "error: no headset"
    panel.say(mended("stereo"))
    assert panel.error == ""
    panel.say(failed("first", source="draw"), failed("second"))
    panel.say(mended("draw"))  # replaced meanwhile: the newer error stays
    assert panel.error == "error: second"
    panel.say(None, (note("a"), None, note("b")))  # nothing, and a tuple in order
    assert panel.message == "b"
    assert Reply.of(note("x"), None, (failed("y"), None)).messages == (note("x"), failed("y"))


def attribute_writes(tree: ast.AST, names: set[str], bases: set[str]) -> list[int]:
    """Lines that assign (or augment) an attribute in ``names`` of an expression ending
    in one of ``bases`` (``stats.draws = ...``, ``self.stats.draws += 1``)."""
    lines = []
    for node in ast.walk(tree):
        targets = node.targets if isinstance(node, ast.Assign) else \
            [node.target] if isinstance(node, (ast.AugAssign, ast.AnnAssign)) else []
        for target in targets:
            for element in (target.elts if isinstance(target, ast.Tuple) else [target]):
                if isinstance(element, ast.Attribute) and element.attr in names:
                    base = element.value
                    base_name = base.attr if isinstance(base, ast.Attribute) else getattr(base, "id", "")
                    if base_name in bases:
                        lines.append(node.lineno)
    return lines


@functools.lru_cache(maxsize=1)
def parsed(package: Path) -> dict[str, ast.AST]:
    """{path from the package's parent: syntax tree} of every module of ``package``, parsed once."""
    return {path.relative_to(package.parent).as_posix(): ast.parse(path.read_text())
            for path in sorted(package.rglob("*.py"))}


def writes_outside(owner: str, names: set[str], bases: set[str], package: Path = VIEWER) -> list[str]:
    """'file:line' of each write of those attributes anywhere in ``package`` but ``owner``'s module."""
    return [f"{name}:{line}" for name, tree in parsed(package).items() if name != owner
            for line in attribute_writes(tree, names, bases)]


def test_the_statistics_and_the_panel_lines_have_one_writer_each():
    """FrameStats's fields are written only in viewer/stats.py (``record`` of a
    DrawReport, ``tick``, ``new_sorter``); the panel's lines only in viewer/state.py."""
    fields = set(FrameStats.__dataclass_fields__)
    assert writes_outside("raygs_viewer/viewer/stats.py", fields, {"stats", "self"}) == []
    assert writes_outside("raygs_viewer/viewer/state.py", {"message", "error", "_message", "_error"},
                          {"panel", "state"}) == []
    assert "record" in vars(FrameStats) and DrawReport.__dataclass_fields__  # the one way a draw reaches them
    # The control: a write of each kind, in a module of its own, is found.
    tree = ast.parse("stats.draws += 1\nself.stats.order_stats, x = (None, None), 1\npanel.error = 'e'\n"
                     "viewer.panel.message = 'm'\nother.draws = 2\n")
    assert attribute_writes(tree, fields, {"stats"}) == [1, 2]
    assert attribute_writes(tree, {"message", "error"}, {"panel"}) == [3, 4]


def test_no_module_keeps_a_host_or_a_viewer_on_an_object():
    """No ``self.host = ...`` / ``self.viewer = ...`` anywhere in the package: a part gets
    what it needs with each call."""
    found = writes_outside("", {"host", "viewer"}, {"self"})
    assert found == []
    assert attribute_writes(ast.parse("self.host = host\n"), {"host"}, {"self"}) == [1]


def test_a_message_is_one_line_whatever_the_error():
    assert failed(ValueError("a\nb"), "loading").text == "error: loading: a b"
    assert isinstance(failed("x"), Message) and failed("x").text == "error: x"

"""Edits of a scene: a selection and the deleted gaussians, each an (N,) bool mask over
the scene's rows, changed by operations that undo and redo.

Two masks, ``selected`` and ``deleted``; what is shown selected is ``selected & ~deleted``
(:attr:`Edits.selection`). Each operation changes exactly one of them, so its undo step
is that mask's change, packed: one bit a gaussian, at most, a step (a step that changes
nothing is not recorded). Deleting a selection leaves its bits in ``selected``: undoing
the delete shows it selected again, as it was.

Operations, as an edit document records them (``Operation.to_json``):

- ``{"op": "select", "how": "set" | "add" | "subtract" | "intersect", "shape": {...}}``
  (shapes: :mod:`raygs_viewer.scene.selection`); a deleted gaussian is never selected;
- ``{"op": "select all"}``, ``{"op": "select none"}``, ``{"op": "invert"}``;
- ``{"op": "delete"}``: the selection; ``{"op": "undelete all"}``;
- ``{"op": "crop", "shape": box or sphere}``: delete every gaussian outside it.

Replaying the operations in order on the same scene gives the same masks: every shape
is computed from the scene and the operation alone.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field, replace
from typing import Callable, Literal, get_args

import numpy as np

from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.selection import Box, Shape, Sphere, shape_from_json

#: How a selection combines with the one before.
How = Literal["set", "add", "subtract", "intersect"]
HOWS: tuple[How, ...] = get_args(How)
#: The operations: two with a shape (select, crop), the others (:data:`PLAIN`) without.
OperationName = Literal["select", "crop", "select all", "select none", "invert", "delete", "undelete all"]
PLAIN: tuple[OperationName, ...] = get_args(OperationName)[2:]
#: The fewest undo steps kept (older steps are forgotten first).
UNDO_STEPS = 256
#: Every state of every Edits gets its own generation: equal generations are equal masks,
#: so a cache of anything made from the masks is keyed on the generation alone.
_GENERATIONS = itertools.count(1)


@dataclass(frozen=True)
class Operation:
    """One edit: ``op``, with a ``shape`` for select and crop and ``how`` a selection
    combines with the last."""

    op: OperationName
    shape: Shape | None = None
    how: How = "set"

    def __post_init__(self) -> None:
        if self.op == "select":
            if self.shape is None or self.how not in HOWS:
                raise ValueError(f"select needs a shape and 'how' one of {', '.join(HOWS)}")
        elif self.op == "crop":
            if not isinstance(self.shape, (Box, Sphere)):
                raise ValueError("crop needs a box or a sphere")
        elif self.op not in PLAIN:
            raise ValueError(f"unknown operation {self.op!r}: select, crop, {', '.join(PLAIN)}")

    def to_json(self) -> dict:
        entry: dict = {"op": self.op}
        if self.op == "select":
            entry["how"] = self.how
        if self.shape is not None:
            entry["shape"] = self.shape.to_json()
        return entry

    @classmethod
    def from_json(cls, entry) -> "Operation":
        """ValueError, saying what is wrong, for anything ``to_json`` does not write."""
        if not isinstance(entry, dict) or not isinstance(entry.get("op"), str):
            raise ValueError("an operation must be an object with an 'op'")
        shape = shape_from_json(entry["shape"]) if "shape" in entry else None
        return cls(entry["op"], shape, entry.get("how", "set"))


@dataclass
class _Step:
    """One undo step: which mask changed, its packed change (XOR), and the operation."""

    mask: str
    change: np.ndarray
    operation: Operation


@dataclass
class Edits:
    """The edits of a scene of ``count`` gaussians: ``selected`` and ``deleted`` (N,) bool,
    ``operations`` applied so far (what the document records; undone ones are not), the
    undo and redo steps (at most ``undo_steps`` of them kept). ``generation``: this
    state's number, new at every change and unique across all edits (a cache's key)."""

    count: int
    undo_steps: int = UNDO_STEPS
    selected: np.ndarray = field(init=False)
    deleted: np.ndarray = field(init=False)
    operations: list[Operation] = field(init=False, default_factory=list)
    _undo: list[_Step] = field(init=False, default_factory=list)
    _redo: list[_Step] = field(init=False, default_factory=list)
    generation: int = field(init=False, default_factory=lambda: next(_GENERATIONS))

    def __post_init__(self) -> None:
        self.selected = np.zeros(self.count, bool)
        self.deleted = np.zeros(self.count, bool)

    @property
    def selection(self) -> np.ndarray:
        """(N,) bool: what is selected and not deleted (shown tinted, deleted by delete)."""
        return self.selected & ~self.deleted

    def grow(self, count: int) -> Edits:
        """These edits of a scene that grew to ``count`` rows, its rows before kept where
        they were (a streamed SOG's finer level): the new rows start neither selected nor
        deleted; the operations and the undo steps carry over (they change only the rows
        they were made on)."""
        if count < self.count:
            raise ValueError(f"edits of {self.count} gaussians cannot grow to {count}")
        grown = Edits(count, self.undo_steps)
        grown.selected[: self.count], grown.deleted[: self.count] = self.selected, self.deleted
        grown.operations = list(self.operations)
        grown._undo = [replace(step, change=_padded(step.change, count)) for step in self._undo]
        grown._redo = [replace(step, change=_padded(step.change, count)) for step in self._redo]
        return grown

    @property
    def edited(self) -> bool:
        """Whether any gaussian is deleted (the scene drawn differs from the file)."""
        return bool(self.deleted.any())

    def can_undo(self) -> bool:
        return bool(self._undo)

    def can_redo(self) -> bool:
        return bool(self._redo)

    def apply(self, scene: Scene, operation: Operation) -> bool:
        """Applies ``operation`` to ``scene`` (this count); True when it changed a mask
        (then it is recorded, undoable, and the redo steps are dropped)."""
        if scene.count != self.count:
            raise ValueError(f"edits of {self.count} gaussians applied to a scene of {scene.count}")
        name, new = self._result(scene, operation)
        change = getattr(self, name) ^ new
        if not change.any():
            return False
        setattr(self, name, new)
        self._undo.append(_Step(name, np.packbits(change), operation))
        del self._undo[: max(0, len(self._undo) - self.undo_steps)]
        self._redo.clear()
        self.operations.append(operation)
        self.generation = next(_GENERATIONS)
        return True

    def _result(self, scene: Scene, operation: Operation) -> tuple[str, np.ndarray]:
        """(the mask ``operation`` changes, its new value)."""
        return RESULTS[operation.op](self, scene, operation)

    def undo(self) -> bool:
        """Undoes the last step; False when there is none."""
        return self._step(self._undo, self._redo, forward=False)

    def redo(self) -> bool:
        """Redoes the last undone step; False when there is none."""
        return self._step(self._redo, self._undo, forward=True)

    def _step(self, source: list[_Step], target: list[_Step], forward: bool) -> bool:
        if not source:
            return False
        step = source.pop()
        change = np.unpackbits(step.change, count=self.count).astype(bool)
        setattr(self, step.mask, getattr(self, step.mask) ^ change)
        target.append(step)
        if forward:
            self.operations.append(step.operation)
        else:
            self.operations.pop()
        self.generation = next(_GENERATIONS)
        return True

    def undo_bytes(self) -> int:
        """Bytes the undo and redo steps hold (each at most ceil(N / 8))."""
        return sum(step.change.nbytes for step in self._undo + self._redo)


def _selected(edits: Edits, scene: Scene, operation: Operation) -> tuple[str, np.ndarray]:
    """A selection by a shape, combined with the one before (a deleted gaussian is never selected)."""
    shape = operation.shape.mask(scene) & ~edits.deleted
    current = edits.selection
    return "selected", {"set": shape, "add": current | shape, "subtract": current & ~shape,
                        "intersect": current & shape}[operation.how]


#: What each operation does: (the mask it changes, its new value) of the edits, the scene
#: and the operation.
RESULTS: dict[OperationName, Callable[[Edits, Scene, Operation], tuple[str, np.ndarray]]] = {
    "select": _selected,
    "crop": lambda edits, scene, operation: ("deleted", edits.deleted | ~operation.shape.mask(scene)),
    "select all": lambda edits, scene, operation: ("selected", ~edits.deleted),
    "select none": lambda edits, scene, operation: ("selected", np.zeros(edits.count, bool)),
    "invert": lambda edits, scene, operation: ("selected", ~edits.deleted & ~edits.selected),
    "delete": lambda edits, scene, operation: ("deleted", edits.deleted | edits.selection),
    "undelete all": lambda edits, scene, operation: ("deleted", np.zeros(edits.count, bool)),
}


def _padded(packed: np.ndarray, count: int) -> np.ndarray:
    """A packed change of fewer rows as one of ``count`` rows (the new rows unchanged)."""
    grown = np.zeros((count + 7) // 8, np.uint8)
    grown[: packed.size] = packed
    return grown


def replay(scene: Scene, operations: list[Operation]) -> Edits:
    """The edits ``operations`` make of ``scene``, applied in order."""
    edits = Edits(scene.count, undo_steps=0)
    for operation in operations:
        edits.apply(scene, operation)
    return edits

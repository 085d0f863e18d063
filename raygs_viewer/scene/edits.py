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

from dataclasses import dataclass, field

import numpy as np

from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.selection import Box, Shape, Sphere, shape_from_json

HOWS = ("set", "add", "subtract", "intersect")
#: Operations without a shape.
PLAIN = ("select all", "select none", "invert", "delete", "undelete all")
#: The fewest undo steps kept (older steps are forgotten first).
UNDO_STEPS = 256


@dataclass(frozen=True)
class Operation:
    """One edit: ``op`` (select, crop, or one of :data:`PLAIN`), with a ``shape`` for
    select and crop and ``how`` a selection combines with the last."""

    op: str
    shape: Shape | None = None
    how: str = "set"

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
    undo and redo steps (at most ``undo_steps`` of them kept)."""

    count: int
    undo_steps: int = UNDO_STEPS
    selected: np.ndarray = field(init=False)
    deleted: np.ndarray = field(init=False)
    operations: list[Operation] = field(init=False, default_factory=list)
    _undo: list[_Step] = field(init=False, default_factory=list)
    _redo: list[_Step] = field(init=False, default_factory=list)
    generation: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        self.selected = np.zeros(self.count, bool)
        self.deleted = np.zeros(self.count, bool)

    @property
    def selection(self) -> np.ndarray:
        """(N,) bool: what is selected and not deleted (shown tinted, deleted by delete)."""
        return self.selected & ~self.deleted

    @property
    def kept(self) -> np.ndarray:
        """(N,) bool: what is not deleted (drawn, exported)."""
        return ~self.deleted

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
        self.generation += 1
        return True

    def _result(self, scene: Scene, operation: Operation) -> tuple[str, np.ndarray]:
        """(the mask ``operation`` changes, its new value)."""
        op, alive = operation.op, ~self.deleted
        if op == "delete":
            return "deleted", self.deleted | self.selection
        if op == "undelete all":
            return "deleted", np.zeros(self.count, bool)
        if op == "crop":
            return "deleted", self.deleted | ~operation.shape.mask(scene)
        if op == "select all":
            return "selected", alive.copy()
        if op == "select none":
            return "selected", np.zeros(self.count, bool)
        if op == "invert":
            return "selected", alive & ~self.selected
        shape = operation.shape.mask(scene) & alive
        current = self.selection
        return "selected", {"set": shape, "add": current | shape, "subtract": current & ~shape,
                            "intersect": current & shape}[operation.how]

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
        self.generation += 1
        return True

    def undo_bytes(self) -> int:
        """Bytes the undo and redo steps hold (each at most ceil(N / 8))."""
        return sum(step.change.nbytes for step in self._undo + self._redo)


def replay(scene: Scene, operations: list[Operation]) -> Edits:
    """The edits ``operations`` make of ``scene``, applied in order."""
    edits = Edits(scene.count, undo_steps=0)
    for operation in operations:
        edits.apply(scene, operation)
    return edits

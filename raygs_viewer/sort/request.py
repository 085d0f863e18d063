"""What a sort is asked for and what it hands back, as values.

A :class:`SortRequest` names everything an order depends on (the view, the cull, the
keys, a streamed scene's levels); its :attr:`~SortRequest.identity` is the one test of
"the same sort". A sorter answers with a :class:`SortResult`: one :class:`Order` per
key, each carrying its indices, its key, the rows it covers and the request it
answers, so whoever draws an order knows what it holds without being told separately,
and "is this order fresh?" is ``order.request == the request I last made``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Mapping, Protocol, Sequence, runtime_checkable

import numpy as np

from raygs_viewer.camera.pinhole import Camera, camera_key
from raygs_viewer.sort.deleted import DeletedRows, deleted_key
from raygs_viewer.sort.keys import SortKey, SortMethod, check_method, checked_keys
from raygs_viewer.sort.lod_choice import LodChoice, LodRequest


@dataclass(frozen=True, eq=False)
class SortRequest:
    """One view's sort.

    camera:       the view the keys are measured from.
    p_min:        the opacity cut-off of the cull.
    dilation:     ``RenderSettings.cull_dilation``: how much a pixel filter widens each
                  support sphere; None keeps everything in front of the camera plane.
    cull_cameras: keep what any of these may see instead of what ``camera`` sees
                  (stereo: both eyes, sorted from their midpoint); None: ``camera``.
    keys:         the sort keys, each sorted once over one cull (the split view may
                  show two); the first is the request's main key.
    levels:       a streamed SOG's levels: a :class:`LodRequest` to choose for
                  ``camera`` first, or a :class:`LodChoice` already made (a frame's
                  tiles and eyes share the frame's); None: the whole scene.
    method:       ``sort.keys``' "auto", "radix" or "float".
    deleted:       gaussians left out of every order, as if deleted (:class:`DeletedRows`);
                  None: none.

    Equal requests (:attr:`identity`) give equal orders. The cameras are private
    copies: a caller may go on changing its own camera's arrays.
    """

    camera: Camera
    p_min: float
    dilation: float | None = 0.0
    cull_cameras: tuple[Camera, ...] | None = None
    keys: tuple[SortKey, ...] = ("depth",)
    levels: LodRequest | LodChoice | None = None
    method: SortMethod = "auto"
    deleted: DeletedRows | None = None

    def __post_init__(self) -> None:
        check_method(self.method)
        keys = checked_keys(self.keys)
        if not keys:
            raise ValueError("a sort request needs at least one sort key")
        set_ = object.__setattr__  # frozen: these are the normal forms of the given values
        set_(self, "keys", keys)
        set_(self, "camera", _snapshot(self.camera))
        set_(self, "p_min", float(self.p_min))
        set_(self, "dilation", None if self.dilation is None else float(self.dilation))
        if self.cull_cameras is not None:
            set_(self, "cull_cameras", tuple(_snapshot(c) for c in self.cull_cameras))

    @cached_property
    def identity(self) -> tuple:
        """Everything the orders depend on, as exact values (a dilation of None, no
        frustum culling, differs from every number)."""
        culled_for = None if self.cull_cameras is None else tuple(camera_key(c) for c in self.cull_cameras)
        return (camera_key(self.camera), self.p_min, self.dilation, culled_for, self.keys,
                _levels_identity(self.levels), self.method, deleted_key(self.deleted))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, SortRequest) and self.identity == other.identity

    def __hash__(self) -> int:
        return hash(self.identity)

def _levels_identity(levels: LodRequest | LodChoice | None):
    if isinstance(levels, LodChoice):
        return levels.spans.tobytes()
    return None if levels is None else levels.key


def _snapshot(camera: Camera) -> Camera:
    """A private copy of the camera's arrays."""
    return replace(camera, R=np.array(camera.R, np.float64), t=np.array(camera.t, np.float64))


@runtime_checkable
class DeviceIndices(Protocol):
    """An order's indices kept where a GPU sort made them: a buffer of ``count`` uint32
    scene rows, back to front, that the renderer binds as it is (no order crosses the
    bus); :meth:`read` fetches a copy for what needs them on the CPU (a screenshot's
    tiles, tests)."""

    @property
    def count(self) -> int: ...

    @property
    def buffer(self) -> object: ...

    @property
    def commands(self) -> object | None:
        """Indirect draw commands whose count the GPU wrote (the renderer draws through
        them), or None."""

    def read(self) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class Order:
    """The gaussians a view draws, back to front.

    indices: (M,) uint32 scene rows, back to front by ``key``, ties in scene order; or,
             from a GPU sort, :class:`DeviceIndices` holding them on the GPU.
    key:     the sort key ("depth" or "distance").
    request: the request it answers (None: an order given by hand, such as a test's).
    choice:  the level-of-detail choice whose rows it holds (None: the whole scene);
             only those rows need preparing for the draw.

    The renderer reads only :attr:`count` and :attr:`spans` and binds the order through
    one method (``GLRenderer.upload_order``), whichever the indices are.
    """

    indices: np.ndarray | DeviceIndices
    key: SortKey = "depth"
    request: SortRequest | None = None
    choice: LodChoice | None = None

    def __post_init__(self) -> None:
        if isinstance(self.indices, DeviceIndices):
            return
        indices = np.asarray(self.indices, np.uint32)
        if indices.ndim != 1:  # a (M,) array stays the very array: the renderer skips re-uploading it
            indices = indices.reshape(-1)
        object.__setattr__(self, "indices", indices)

    @property
    def on_device(self) -> bool:
        """Whether the indices are on the GPU (:class:`DeviceIndices`)."""
        return isinstance(self.indices, DeviceIndices)

    @property
    def count(self) -> int:
        return int(self.indices.count if self.on_device else self.indices.size)

    def host_indices(self) -> np.ndarray:
        """(M,) uint32 indices on the CPU: the array, or a copy read from the GPU."""
        return self.indices.read() if self.on_device else self.indices

    @property
    def spans(self) -> np.ndarray | None:
        """(S, 2) int64 ascending [start, stop) rows the order may hold; None: any row."""
        return None if self.choice is None else self.choice.spans

    def answers(self, request: SortRequest | None) -> bool:
        """Whether this order is the answer to ``request`` (its view, cull, keys and levels)."""
        return request is not None and self.request == request

    def with_indices(self, indices: np.ndarray) -> "Order":
        """The same order's subset ``indices`` (relative order kept by the caller): a tile's."""
        return replace(self, indices=indices)


@dataclass(frozen=True, eq=False)
class SortResult:
    """A sorter's answer to one request.

    request: what was asked.
    orders:  {key: Order} for every key of the request, one cull for all.
    choice:  the level-of-detail choice made for the request (None: the whole scene).
    times:   {"choice", "wait", "cull", "sort"} wall times in seconds (``time.perf_counter``):
             the level choice (where one was made), the wait for another thread's sort on
             the same sorter, the cull with the keys, the sort.
    serial, requested_at, finished_at: the sort thread's serial of the request and the
             ``perf_counter`` times it was queued and finished (0 for a sort run in place):
             the drawn order's age is ``perf_counter() - requested_at``.
    """

    request: SortRequest
    orders: Mapping[str, Order]
    choice: LodChoice | None = None
    times: Mapping[str, float] = field(default_factory=dict)
    serial: int = 0
    requested_at: float = 0.0
    finished_at: float = 0.0

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(self.orders)

    @property
    def order(self) -> Order:
        """The order by the request's main (first) key."""
        return self.orders[self.request.keys[0]]

    def order_for(self, key: str) -> Order | None:
        """The order sorted by ``key``; None when this sort was not asked for it."""
        return self.orders.get(key)

    @property
    def seconds(self) -> float:
        """The whole sort's wall time."""
        return float(sum(self.times.values()))


def keys_of(sides: Sequence[SortKey | None]) -> tuple[SortKey, ...]:
    """The sort keys of every side shown, the first side's first, each once."""
    return tuple(dict.fromkeys(key for key in sides if key is not None))

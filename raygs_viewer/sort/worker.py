"""Depth sorting off the frame loop: the window asks for a sort and draws with the
newest finished order, never waiting for one.

One daemon thread per :class:`BackgroundSorter` runs ``sorter.orders`` on the
newest requested view: one cull, then one sort per key the request names (the A/B
split view may show a depth-ordered side beside a distance-ordered one), so a
result holds an order per key. A request that arrives while a sort runs waits in a
single slot; a newer request replaces it (only the newest view matters, and a
moving camera would otherwise build a backlog of stale sorts). Locks are held
only to swap references and bump counters, never across a sort, so
:meth:`BackgroundSorter.request` and :meth:`BackgroundSorter.latest` return at
once however long a sort takes.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field, replace
from typing import Mapping, Protocol, Sequence

import numpy as np

from raygs_viewer.camera.pinhole import Camera, camera_key
from raygs_viewer.errors import one_line
from raygs_viewer.sort.closing import Closable
from raygs_viewer.sort.lod_choice import LodChoice, LodRequest

__all__ = ["BackgroundSorter", "SortResult", "Sorter"]


class Sorter(Protocol):
    """What :class:`BackgroundSorter` runs: :class:`raygs_viewer.sort.depth.DepthSorter` or a test double.
    ``orders`` returns {key: (M,) back-to-front indices} for each of ``keys``. A ``close()``
    method, where the sorter has one, is called when the worker exits."""

    def orders(self, camera: Camera, p_min: float, *, dilation: float | None = 0.0,
               cull_cameras: tuple[Camera, ...] | None = None,
               keys: Sequence[str] = ("depth",)) -> Mapping[str, np.ndarray]: ...


@dataclass(frozen=True)
class SortResult:
    """One finished sort.

    order:   (M,) uint32 gaussian indices, back to front by the request's first key
             (what ``DepthSorter.order`` returns for it).
    serial:  the serial :meth:`BackgroundSorter.request` returned for the view (1, 2, ...).
    camera:  the view it was sorted for (a private copy of the requested camera).
    p_min:   the opacity cut-off it culled with.
    dilation: the cull dilation it culled with (``RenderSettings.cull_dilation``; None:
             no frustum culling).
    seconds: how long ``sorter.order`` took (``time.perf_counter``), for the statistics panel.
    cull_cameras: the cameras it culled for (None: ``camera``'s own view; stereo: both eyes).
    orders:  {key: order} for every key asked ("depth", "distance"); all hold the same
             gaussians (one cull), each sorted by its key. ``orders[keys[0]] is order``.
    requested_at, finished_at: ``time.perf_counter()`` when the request was queued and
             when its sort finished: the drawn order's age is ``perf_counter() - requested_at``
             (it shows the view as it was then), its latency ``finished_at - requested_at``.
    lod:     the level-of-detail choice the orders hold (None: the whole scene); its age is the order's.
    lod_key: the ``LodRequest.key`` the choice was made for (None: none): what tells the
             window whether the drawn choice is the one its settings and scene now ask for.
    """

    order: np.ndarray
    serial: int
    camera: Camera
    p_min: float
    seconds: float
    dilation: float | None = 0.0
    cull_cameras: tuple[Camera, ...] | None = None
    orders: Mapping[str, np.ndarray] = field(default_factory=dict)
    requested_at: float = 0.0
    finished_at: float = 0.0
    lod: LodChoice | None = None
    lod_key: tuple | None = None

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(self.orders)

    def order_for(self, key: str) -> np.ndarray | None:
        """The order sorted by ``key``; None when this sort was not asked for it."""
        return self.orders.get(key)


@dataclass(frozen=True)
class _Request:
    serial: int
    camera: Camera
    p_min: float
    dilation: float | None
    cull_cameras: tuple[Camera, ...] | None
    keys: tuple[str, ...]
    requested_at: float
    lod: LodRequest | None = None


def _dilation(value: float | None) -> float | None:
    return None if value is None else float(value)


def _keys(keys: Sequence[str]) -> tuple[str, ...]:
    """The distinct sort keys, first-named first (at least one)."""
    distinct = tuple(dict.fromkeys(keys))
    if not distinct:
        raise ValueError("a sort request needs at least one sort key")
    return distinct


def _view_key(camera: Camera, p_min: float, dilation: float | None = 0.0,
              cull_cameras: tuple[Camera, ...] | None = None, keys: Sequence[str] = ("depth",),
              lod: LodRequest | None = None) -> tuple:
    """Everything the orders depend on, as exact values: equal keys give equal orders
    (a dilation of None, no frustum culling, differs from every number)."""
    culled_for = None if cull_cameras is None else tuple(camera_key(c) for c in cull_cameras)
    return camera_key(camera) + (float(p_min), _dilation(dilation), culled_for, _keys(keys),
                                 None if lod is None else lod.key)


def _snapshot(camera: Camera) -> Camera:
    """A private copy: the caller may update its camera's arrays in place while the
    worker is still sorting for them."""
    return replace(camera, R=np.array(camera.R, np.float64), t=np.array(camera.t, np.float64))




class BackgroundSorter(Closable):
    """Sorts on a daemon worker thread; the frame loop only calls :meth:`request` and :meth:`latest`.

    Counters (plain ints, read without locking by the statistics panel and tests):

    - ``requested``: requests queued, i.e. serials handed out (identical repeats not counted);
    - ``repeated``: requests identical to the last one queued, answered with its serial;
    - ``started``: sorts begun; ``finished``: sorts that produced a result;
    - ``failed``: sorts whose ``orders`` raised;
    - ``superseded``: queued requests replaced by a newer one before they started.

    ``requested == started + superseded + (1 if a request is waiting else 0)``.
    ``error`` is the one-line message of the last failed sort, cleared by the next
    successful one; a failed view is not retried until a different view (or p_min,
    dilation or keys) is requested, so a frame loop re-requesting the same view cannot
    spin on it.
    """

    def __init__(self, sorter: Sorter) -> None:
        self._sorter = sorter
        self._cond = threading.Condition()
        self._pending: _Request | None = None
        self._latest: SortResult | None = None
        self._answered = 0  # highest serial whose sort finished or failed; wait() compares with it
        self._last_key: tuple | None = None
        self._closed = False
        self.requested = 0
        self.repeated = 0
        self.started = 0
        self.finished = 0
        self.failed = 0
        self.superseded = 0
        self.error: str | None = None
        self._thread = threading.Thread(target=self._run, name="raygs-sort", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ frame-loop side

    def request(self, camera: Camera, p_min: float, dilation: float | None = 0.0,
                cull_cameras: tuple[Camera, ...] | None = None, keys: Sequence[str] = ("depth",),
                lod: LodRequest | None = None) -> int:
        """Non-blocking. Queues a sort for this view and returns its serial; a request
        not yet started is replaced by the newer one (only the newest view matters). A
        request equal to the last one queued (same camera R, t, intrinsics, p_min,
        dilation and keys) is not queued again: returns the old serial. ``dilation`` goes
        to ``sorter.orders(camera, p_min, dilation=dilation, ...)`` (see
        :meth:`raygs_viewer.render.settings.RenderSettings.cull_dilation`), and ``cull_cameras``
        (stereo: both eyes; None: ``camera``) likewise. ``keys``: the sort keys whose
        orders the result must hold ("depth", "distance"; culled once, sorted once per
        distinct key; another set of keys is another request). ``lod``: choose the levels
        of a streamed scene for the view first and cull and sort only those
        (``SortResult.lod``). Raises RuntimeError after :meth:`close`."""
        keys = _keys(keys)
        key = _view_key(camera, p_min, dilation, cull_cameras, keys, lod)
        with self._cond:
            if self._closed:
                raise RuntimeError("BackgroundSorter.request after close()")
            if key == self._last_key:
                self.repeated += 1
                return self.requested
            self.requested += 1
            if self._pending is not None:
                self.superseded += 1
            cull = None if cull_cameras is None else tuple(_snapshot(c) for c in cull_cameras)
            self._pending = _Request(self.requested, _snapshot(camera), float(p_min), _dilation(dilation), cull,
                                     keys, time.perf_counter(), lod)
            self._last_key = key
            self._cond.notify_all()
            return self.requested

    def latest(self) -> SortResult | None:
        """Non-blocking: the newest finished result (None before the first)."""
        return self._latest  # one reference read: atomic, no lock needed

    # ------------------------------------------------------------------ scripted side

    def wait(self, serial: int, timeout: float | None = None) -> SortResult | None:
        """Blocks until request ``serial`` is answered (for screenshots and tests, never
        the frame loop) and returns the newest result, whose serial is >= ``serial``.

        Returns None when ``timeout`` (seconds) passes first, when the sorter is closed
        first, or when that request's sort failed with no newer result (see ``error``).
        """
        with self._cond:
            self._cond.wait_for(lambda: self._answered >= serial or self._closed, timeout)
            latest = self._latest
        return latest if latest is not None and latest.serial >= serial else None

    def close(self) -> None:
        """Stops the worker and drops a queued request. Returns at once even while a
        sort runs: the daemon thread finishes that sort, publishes it, closes the sorter
        (its ``close()``, if it has one: a :class:`DepthSorter`'s thread pool) and exits;
        :meth:`join` waits for that."""
        with self._cond:
            self._closed = True
            self._pending = None
            self._cond.notify_all()

    def join(self, timeout: float | None = None) -> bool:
        """Waits until the worker has exited after :meth:`close` (and closed the sorter);
        True when it has."""
        self._thread.join(timeout)
        return not self._thread.is_alive()

    # ------------------------------------------------------------------ worker

    def _run(self) -> None:
        try:
            self._serve()
        finally:
            close = getattr(self._sorter, "close", None)
            if close is not None:
                close()

    def _serve(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._pending is not None or self._closed)
                if self._closed:
                    return
                request, self._pending = self._pending, None
                self.started += 1
            begin = time.perf_counter()
            try:
                choice = None if request.lod is None else request.lod.choose(request.camera)
                spans = {} if choice is None else {"spans": choice.spans}
                sorted_ = self._sorter.orders(request.camera, request.p_min, dilation=request.dilation,
                                              cull_cameras=request.cull_cameras, keys=request.keys, **spans)
                orders = {key: np.asarray(sorted_[key], dtype=np.uint32) for key in request.keys}
            except Exception as exc:  # reported in .error; the thread must keep serving
                with self._cond:
                    self.failed += 1
                    self.error = f"{type(exc).__name__}: {one_line(exc)}" if str(exc).strip() else type(exc).__name__
                    self._answered = max(self._answered, request.serial)
                    self._cond.notify_all()
                continue
            finished = time.perf_counter()
            result = SortResult(orders[request.keys[0]], request.serial, request.camera, request.p_min,
                                finished - begin, request.dilation, request.cull_cameras, orders,
                                request.requested_at, finished, choice,
                                None if request.lod is None else request.lod.key)
            with self._cond:
                self._latest = result
                self.finished += 1
                self.error = None
                self._answered = max(self._answered, request.serial)
                self._cond.notify_all()

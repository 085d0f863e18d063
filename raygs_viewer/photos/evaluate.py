"""A model's renders against the photos of its capture, view by view (docs/evaluation.md).

Each view's camera is rendered with the GL renderer over the dataset's background, the
render clipped to 0..1 as the 3DGS evaluation clamps it, and compared with the photo
(:func:`photos.dataset.load_photo`: at the camera's size, alpha over the same
background). A view whose photo cannot be used is skipped with its one-line reason and
the others go on; Ctrl-C keeps the views done and marks the result interrupted.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from raygs_viewer.capture.screenshot import render_tiled
from raygs_viewer.errors import UserError
from raygs_viewer.photos.dataset import Dataset, PhotoView, load_photo
from raygs_viewer.photos.metrics import Lpips, flip, psnr, ssim_3dgs
from raygs_viewer.render.settings import RenderSettings
from raygs_viewer.render.sorting import exact_order
from raygs_viewer.sort.depth import DepthSorter

#: The metrics every view has, in the order reports list them; LPIPS is optional.
METRICS = ("psnr", "ssim", "flip", "lpips")

#: progress(done, total, name): after each view, scored or skipped.
Progress = Callable[[int, int, str], None]


@dataclass(frozen=True)
class ViewScore:
    """One view's metrics: ``psnr`` in dB (inf for a render identical to its photo),
    ``ssim`` (the 3DGS SSIM), ``flip`` (mean FLIP error), ``lpips`` (None without the extra)."""

    name: str
    psnr: float
    ssim: float
    flip: float
    lpips: float | None = None

    def value(self, metric: str) -> float | None:
        return getattr(self, metric)


@dataclass(frozen=True)
class SkippedView:
    """A view left out, and the one line saying why (naming the file)."""

    name: str
    reason: str


@dataclass
class EvaluationResult:
    """``scores`` and ``skipped`` in the order the views were taken; ``total``: the
    views asked for; ``interrupted``: Ctrl-C stopped it before the last; ``lpips_note``:
    why LPIPS is missing (None when it was computed)."""

    settings: RenderSettings
    total: int
    scores: list[ViewScore] = field(default_factory=list)
    skipped: list[SkippedView] = field(default_factory=list)
    interrupted: bool = False
    lpips_note: str | None = None

    @property
    def done(self) -> int:
        return len(self.scores) + len(self.skipped)

    def mean(self) -> dict[str, float | None]:
        """Each metric's mean over the scored views, as the 3DGS evaluation averages
        them (PSNR too is the mean of the views' PSNRs); None where no view has it."""
        means = {}
        for metric in METRICS:
            values = [score.value(metric) for score in self.scores if score.value(metric) is not None]
            means[metric] = float(np.mean(values)) if values else None
        return means

    def worst(self, count: int) -> list[ViewScore]:
        """The ``count`` views of lowest PSNR, worst first (ties in view order)."""
        return sorted(self.scores, key=lambda score: score.psnr)[:count]


def evaluation_settings(settings: RenderSettings, dataset: Dataset) -> RenderSettings:
    """``settings`` over the dataset's background: the model was trained against it."""
    return replace(settings, background=tuple(dataset.background))


def render_view(renderer, sorter: DepthSorter, view: PhotoView, settings: RenderSettings) -> np.ndarray:
    """(H, W, 3) float32 in 0..1: the view's camera rendered (RGB over the background)
    with an exact sort by ``sorter``, in tiles as screenshots are, so full-size photos
    beyond the GPU's largest target still compare."""
    order = exact_order(sorter, view.camera, settings)
    return np.clip(render_tiled(renderer, sorter, order, view.camera, settings)[..., :3], 0.0, 1.0)


def score_view(name: str, photo: np.ndarray, render: np.ndarray, lpips: Lpips | None = None) -> ViewScore:
    """The metrics of ``render`` against ``photo`` (both (H, W, 3) in 0..1)."""
    return ViewScore(name, psnr(photo, render), ssim_3dgs(photo, render), flip(photo, render),
                     None if lpips is None else lpips(photo, render))


def evaluate(dataset: Dataset, views: Sequence[PhotoView], renderer, settings: RenderSettings, *,
             progress: Progress | None = None, lpips: Lpips | None = None,
             lpips_note: str | None = None) -> EvaluationResult:
    """Scores every view of ``views`` (a split of ``dataset``) rendered by ``renderer``
    (a GLRenderer of the model) with ``settings``, the background replaced by the
    dataset's. ``lpips``: the metric (photos.metrics.open_lpips), ``lpips_note``: why
    it is missing. A photo that fails to load (UserError) skips its view; Ctrl-C
    (KeyboardInterrupt, also from ``progress``) ends it with what is done."""
    settings = evaluation_settings(settings, dataset)
    result = EvaluationResult(settings, len(views), lpips_note=lpips_note)
    with DepthSorter(renderer.scene) as sorter:
        try:
            for view in views:
                try:
                    photo = load_photo(view, dataset.background)
                except UserError as exc:
                    result.skipped.append(SkippedView(view.name, str(exc).splitlines()[0]))
                else:
                    render = render_view(renderer, sorter, view, settings)
                    result.scores.append(score_view(view.name, photo, render, lpips))
                if progress is not None:
                    progress(result.done, result.total, view.name)
        except KeyboardInterrupt:
            result.interrupted = True
    return result


def finite_or_none(value: float | None) -> float | None:
    """``value`` for a report: None for an infinite PSNR (JSON has no infinity)."""
    return None if value is None or not math.isfinite(value) else value

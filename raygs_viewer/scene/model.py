"""Gaussian scenes: the activated, validated arrays every later stage reads.

Loading them from any file format read lives in :mod:`raygs_viewer.scene.io`; the
built-in demo scene in :mod:`raygs_viewer.scene.demo`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: f_rest count -> SH degree (section 2 of the maths page).
SH_DEGREE_OF_REST_COUNT = {0: 0, 9: 1, 24: 2, 45: 3}


def sh_coefficient_count(degree: int) -> int:
    """Coefficients per colour channel for an SH degree: (d + 1)^2."""
    return (degree + 1) ** 2


@dataclass(frozen=True)
class FileAxes:
    """The axes a file stored its gaussians in, when they may differ from the Scene's
    (a ``.spz``: see :mod:`raygs_viewer.scene.spz_format`); the reader converted them.

    assumed:  the convention the reader was told to take for a file that names none,
              "rub" or "rdf" (``spz_format.SPZ_AXES``): the option it was read with.
    declared: the coordinate system the file names itself ("RUB", "RDF", "LUF", ...),
              which wins over ``assumed``; "" when it names none.
    """

    assumed: str
    declared: str = ""

    @property
    def stored(self) -> str:
        """The system the gaussians were read as: "RUB", "RDF", ..."""
        return self.declared or self.assumed.upper()


@dataclass(frozen=True)
class Scene:
    """N activated gaussians in world space (OpenCV axes), float32 throughout.

    positions:  (N, 3) float32, centres p.
    rotations:  (N, 4) float32, unit quaternions (w, x, y, z).
    scales:     (N, 3) float32, linear standard deviations s > 0 (any 3D filter
                already fused in).
    opacities:  (N,)   float32 in [0, 1] (0 and 1 exactly for logits -inf/+inf).
    sh:         (N, (d+1)^2, 3) float32; sh[i, k, c] is SH coefficient k of
                colour channel c (k = 0 is the DC term).
    sh_degree:  d in 0..3.
    filter_fused: True when the file carried a ``filter_3D`` column that was fused.
    source:     where it came from (a path, or "demo").
    dropped:    invalid gaussians skipped at load, by reason -> count.
    format:     the file format it was read from, with its version where it has one
                (its reader's name for it: "INRIA PLY", ".splat", "spz v3",
                "PlayCanvas compressed PLY", "SOG v2", ...); "" for a scene made in memory.
    axes:       for a file whose stored axes may differ from these (a .spz), what they
                were and how the reader knew (:class:`FileAxes`); None otherwise.
    file_rows:  (N,) int64, the row of each gaussian in its file, where they differ from
                0..N-1 (the reader dropped invalid rows, or the scene is a subset of
                another: :meth:`rows`); None where gaussian i is the file's row i.
    """

    positions: np.ndarray
    rotations: np.ndarray
    scales: np.ndarray
    opacities: np.ndarray
    sh: np.ndarray
    sh_degree: int
    filter_fused: bool = False
    source: str = ""
    dropped: dict[str, int] = field(default_factory=dict)
    format: str = ""
    axes: FileAxes | None = None
    file_rows: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = self.positions.shape[0]
        expected = {
            "positions": (n, 3),
            "rotations": (n, 4),
            "scales": (n, 3),
            "opacities": (n,),
            "sh": (n, sh_coefficient_count(self.sh_degree), 3),
        }
        for name, shape in expected.items():
            array = getattr(self, name)
            if array.shape != shape or array.dtype != np.float32:
                raise ValueError(f"Scene.{name}: expected float32 {shape}, got {array.dtype} {array.shape}")
        if self.file_rows is not None and (self.file_rows.shape != (n,) or self.file_rows.dtype != np.int64):
            raise ValueError(f"Scene.file_rows: expected int64 {(n,)}, got {self.file_rows.dtype} {self.file_rows.shape}")

    @property
    def count(self) -> int:
        return int(self.positions.shape[0])

    @property
    def rows_in_file(self) -> np.ndarray:
        """(N,) int64: the file row of each gaussian (``file_rows``, or 0..N-1)."""
        return np.arange(self.count, dtype=np.int64) if self.file_rows is None else self.file_rows

    def rows(self, rows: np.ndarray, format_: str | None = None) -> "Scene":
        """The gaussians at ``rows`` ((K,) int64 indices, or an (N,) bool mask) as a Scene
        of their own, in the order given, each still knowing its file row; source, drops
        and axes kept, the format too unless ``format_`` is given."""
        rows = np.flatnonzero(rows) if np.asarray(rows).dtype == bool else np.asarray(rows, np.int64)
        return Scene(self.positions[rows], self.rotations[rows], self.scales[rows], self.opacities[rows],
                     self.sh[rows], self.sh_degree, self.filter_fused, self.source, dict(self.dropped),
                     self.format if format_ is None else format_, self.axes, self.rows_in_file[rows])

    def with_sh_degree(self, degree: int) -> "Scene":
        """The same scene with SH truncated to ``degree`` (<= the scene's)."""
        degree = max(0, min(int(degree), self.sh_degree))
        if degree == self.sh_degree:
            return self
        return Scene(
            self.positions, self.rotations, self.scales, self.opacities,
            np.ascontiguousarray(self.sh[:, : sh_coefficient_count(degree)]),
            degree, self.filter_fused, self.source, dict(self.dropped), self.format, self.axes, self.file_rows,
        )

"""PlayCanvas's compressed PLY: a ``chunk`` element of per-256-gaussian bounds and packed
``vertex`` words (SuperSplat's and splat-transform's export).

NOTE: not implemented yet (issue 18): a file in this layout is refused in one line.
"""

from __future__ import annotations

from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.ply_header import PlyElement
from raygs_viewer.scene.reading import Reporter, file_error


def load_compressed_ply(path, shown: str, report: Reporter, chunk_bytes: int, header_bytes: int,
                        elements: list[PlyElement], refusal: str | None) -> Scene:
    """The Scene of a compressed PLY whose header :func:`parse_header` has read."""
    raise file_error(shown, "PlayCanvas compressed PLY files are not supported yet")

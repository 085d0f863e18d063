"""PlayCanvas's SOG, version 2: WebP images and a ``meta.json``, bundled in a zip
(``.sog``) or side by side in a folder.

NOTE: not implemented yet (issue 18): a SOG scene is refused in one line.
"""

from __future__ import annotations

from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.reading import Reporter, file_error


def load_sog(path, shown: str, report: Reporter, chunk_bytes: int) -> Scene:
    """``path``: a bundled .sog file, or an unbundled scene's meta.json."""
    raise file_error(shown, "SOG files are not supported yet")

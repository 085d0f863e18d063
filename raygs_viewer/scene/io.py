"""Loading Gaussian scenes from disk: INRIA PLY, the 32-byte ``.splat`` format, Niantic's
``.spz``, PlayCanvas's compressed PLY and SOG (a ``.sog`` zip or a ``meta.json``).

Everything here follows section 2 of the maths page (``raygs-math.md``). The
public entry points:

- :func:`load_scene` reads a file into an activated, validated :class:`Scene`.
- :func:`dropped_summary` turns ``scene.dropped`` into one line per reason.
- :func:`describe` / :func:`format_description` give the ``info`` statistics.

Each format has its reader module (``load_<format>(source, report, chunk_bytes)``, the
:class:`~raygs_viewer.scene.source.SceneSource` read),
and :data:`FORMATS` says which names and first bytes choose it: a new format is a reader
module and a row there. The readers: :mod:`~raygs_viewer.scene.ply_file` (INRIA PLY,
handing PlayCanvas's compressed layout to :mod:`~raygs_viewer.scene.compressed_ply`;
the header in :mod:`~raygs_viewer.scene.ply_header`),
:mod:`~raygs_viewer.scene.splat_file`, :mod:`~raygs_viewer.scene.spz_file` and
:mod:`~raygs_viewer.scene.sog_file`. What they share: :mod:`~raygs_viewer.scene.progress`
(progress and cancel points) and :mod:`~raygs_viewer.scene.reading` (one-line errors,
dropping invalid gaussians, building the Scene); :mod:`~raygs_viewer.scene.describe`
gives the statistics.

Bad input raises :class:`UserError` with a one-line message that starts with the
path as given (``scene.ply: property 'scale_0' is double, expected float``).

Decisions (the maths page leaves these open):

- An empty scene (``element vertex 0``, or an empty ``.splat`` file) is valid:
  N = 0, with the SH degree the header declares.
- Invalid gaussians are dropped, not fatal; each is counted under the *first*
  reason that applies, in this order: ``nan`` (a NaN in any used property,
  ``filter_3D`` included), ``infinite position``, ``infinite scale`` (an
  infinite log-scale, or exp(log-scale) or the fused scale overflowing float32),
  ``zero scale`` (an axis whose activated, fused scale is exactly 0 in float32,
  e.g. a log-scale of -inf or below about -103.3), ``negative scale`` (``.splat``
  only, whose scales are linear), ``infinite rotation``, ``zero quaternion``,
  ``infinite colour`` (an infinite SH coefficient: it would render as NaN).
  Tiny but positive scales (float32 subnormals included, real files carry
  log-scales of about -23) are kept unchanged. Opacity logits of +/-inf are
  valid and give opacity exactly 1 / 0.
- Unknown extra vertex properties (any type, lists excepted) and normals are
  ignored; only the properties used must be float32. Other elements (before or
  after ``vertex``) are allowed; their sizes count towards the size check.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

from raygs_viewer.scene.describe import describe, dropped_summary, format_description
from raygs_viewer.scene.lod_file import load_level, lod_index_file
from raygs_viewer.scene.model import Scene
from raygs_viewer.scene.ply_file import load_ply
from raygs_viewer.scene.progress import READ_CHUNK_BYTES, ProgressCallback, Reporter
from raygs_viewer.scene.reading import DROP_REASONS, file_error
from raygs_viewer.scene.sog_file import load_sog
from raygs_viewer.scene.sog_source import is_sog_folder
from raygs_viewer.scene.source import SCENE_FILES, SceneSource
from raygs_viewer.scene.splat_file import SPLAT_ROW_BYTES, load_splat
from raygs_viewer.scene.spz_file import load_spz

#: The first bytes that name a format whatever the file's name: gzip (.spz versions 2
#: and 3), an uncompressed .spz (version 4's header), a zip (a bundled .sog).
GZIP_MAGIC = b"\x1f\x8b"
SPZ_MAGIC = b"NGSP"
ZIP_MAGIC = b"PK\x03\x04"

#: ``read(source, report, chunk_bytes)``: one format's reader of ``source.path`` (named
#: so in messages), with the source's options; ``chunk_bytes`` how much is read between
#: progress points.
FormatReader = Callable[[SceneSource, Reporter, int], Scene]


class SceneFormat(NamedTuple):
    """A file format :func:`load_scene` reads: ``read(source, report, chunk_bytes)``
    reads it; a name ending in one of ``suffixes`` chooses it whatever the bytes say (a
    .ply that is a zip is a broken PLY, not a SOG); for other names, ``magic(first four
    bytes)`` does."""

    suffixes: tuple[str, ...]
    magic: Callable[[bytes], bool]
    read: FormatReader


#: Every format read, in the order their magic is tried (no two magics overlap). A
#: .ply's own reader tells INRIA's layout from PlayCanvas's compressed one by its header.
FORMATS = (
    SceneFormat((".ply",), lambda magic: magic[:3] == b"ply", load_ply),
    SceneFormat((".splat",), lambda magic: False, load_splat),  # headerless rows: only its name says .splat
    SceneFormat((".spz",), lambda magic: magic[:2] == GZIP_MAGIC or magic == SPZ_MAGIC, load_spz),
    SceneFormat((".sog", ".json"), lambda magic: magic == ZIP_MAGIC, load_sog),
)
#: The names of scene files, for the command line's router and the panel's hint. A SOG
#: meta.json is a scene only by its content: every other .json (cameras, paths) is not.
SCENE_SUFFIXES = tuple(suffix for format_ in FORMATS for suffix in format_.suffixes if suffix != ".json")

__all__ = [
    "DROP_REASONS",
    "FORMATS",
    "READ_CHUNK_BYTES",
    "SCENE_FILES",
    "SCENE_SUFFIXES",
    "SPLAT_ROW_BYTES",
    "ProgressCallback",
    "describe",
    "dropped_summary",
    "format_description",
    "load_scene",
]


def load_scene(source: SceneSource | str | os.PathLike, *, progress: ProgressCallback | None = None,
               cancel: threading.Event | None = None, chunk_bytes: int | None = None,
               lod: int | None = None) -> Scene:
    """Read a scene file (:data:`SCENE_FILES`), ``source`` (a path: read with the default
    options), into an activated :class:`Scene`.

    The format is chosen by the extension (``.splat``, ``.spz``, ``.sog``, ``.json``;
    a ``.ply`` is INRIA's or PlayCanvas's compressed layout by its header), and for
    other names by the first bytes (``ply``, gzip or ``NGSP`` for .spz, a zip for SOG):
    see :data:`FORMATS`. A folder holding a SOG ``meta.json`` is that scene. Raises
    :class:`UserError` for anything that is not a readable scene file. Invalid
    gaussians are dropped and counted in ``scene.dropped`` (see the module docstring).

    ``progress(fraction, stage)`` is called from the loading thread: first with
    0.0, then after every :data:`READ_CHUNK_BYTES` of gaussian data and at each
    later stage, with a non-decreasing fraction; the last call is ``(1.0, "done")``.
    When ``cancel`` is set, loading stops at the next progress point (whether or
    not a callback is given) with ``UserError("loading cancelled")``. ``chunk_bytes``
    replaces :data:`READ_CHUNK_BYTES` (tests read tiny files in many chunks).

    A streamed SOG (its ``lod-meta.json``, or the folder holding it) reads as one level,
    ``lod`` (default 0, the finest), with its environment
    (:func:`~raygs_viewer.scene.lod_file.load_level`); the view-dependent choice between
    levels needs all of them, :func:`~raygs_viewer.scene.lod_file.load_lod`.

    The source's options reach every reader (a ``.spz`` takes its axes from it; the
    source checked them when it was made).
    """
    if not isinstance(source, SceneSource):
        source = SceneSource(source)
    path = source.path
    if lod_index_file(path) is not None:
        try:
            return load_level(path, 0 if lod is None else lod, progress=progress, cancel=cancel,
                              chunk_bytes=READ_CHUNK_BYTES if chunk_bytes is None else chunk_bytes)
        except (OSError, MemoryError) as exc:
            raise source.read_error(exc) from None
    if lod is not None:
        raise file_error(path, "not a streamed SOG: a level (--lod) applies to a lod-meta.json scene")
    report = Reporter(progress, cancel)
    scene = _load(source, report, READ_CHUNK_BYTES if chunk_bytes is None else chunk_bytes)
    report(1.0, "done")
    return scene


def _load(source: SceneSource, report: Reporter, chunk_bytes: int) -> Scene:
    path = shown = source.path
    report(0.0, "reading")
    if not os.path.exists(path):  # found before a reader opens it: the same words as its OSError's
        raise source.read_error(FileNotFoundError(path))
    sog_folder = is_sog_folder(path)
    if os.path.isdir(path) and not sog_folder:
        raise source.read_error(IsADirectoryError(path))
    if not os.path.isfile(path) and not sog_folder:
        raise file_error(shown, "not a regular file")
    try:
        read = load_sog if sog_folder else _reader(path, shown)
        return read(source, report, chunk_bytes)
    except (OSError, MemoryError) as exc:
        raise source.read_error(exc) from None


def _reader(path: str | os.PathLike, shown: str) -> FormatReader:
    """The reader of the file ``path``: by its name, else by its first bytes."""
    suffix = Path(path).suffix.lower()
    for scene_format in FORMATS:
        if suffix in scene_format.suffixes:
            return scene_format.read
    with open(path, "rb") as f:
        magic = f.read(4)
    for scene_format in FORMATS:
        if scene_format.magic(magic):
            return scene_format.read
    raise file_error(shown, f"unrecognised file format: expected a scene file ({SCENE_FILES})")


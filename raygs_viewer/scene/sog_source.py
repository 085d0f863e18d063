"""Where a SOG scene's bytes come from: a zip bundle (``.sog``) or a folder holding a
``meta.json`` beside its images, read defensively.

Hostile archives: every member used is read by its central-directory entry with a cap on
its declared size, decompressed with a bound one byte past that size (a member that
inflates to more, or less, than it declares is refused), and checked against its CRC.
An unbundled ``meta.json`` may only name images inside its own folder.

This is also the one place that decides what an unbundled scene is: see
:func:`is_sog_folder` and :func:`meta_file`.
"""

from __future__ import annotations

import os
import struct
import zipfile
import zlib
from collections.abc import Callable
from typing import Protocol

from raygs_viewer.scene.reading import file_error, shown_token

META_NAME = "meta.json"
#: meta.json holds three 256-entry codebooks and file names: about 10 KB.
MAX_META_BYTES = 4 << 20
_ZIP_MAGIC = b"PK\x03\x04"


def is_sog_folder(path) -> bool:
    """Whether ``path`` is the folder of an unbundled SOG scene: a folder holding a meta.json."""
    return os.path.isdir(path) and os.path.isfile(os.path.join(path, META_NAME))


def meta_file(path) -> str | os.PathLike:
    """The file a SOG path names: a folder stands for the meta.json inside it (which may
    be missing); a file is itself."""
    return os.path.join(path, META_NAME) if os.path.isdir(path) else path


def is_bundle(path) -> bool:
    """Whether the file ``path`` is a zip: a bundled scene, whatever its name."""
    with open(path, "rb") as f:
        return f.read(4) == _ZIP_MAGIC


class SogSource(Protocol):
    """A SOG scene's files: its meta.json and the images that names, each by its name."""

    shown_meta: str

    def read_meta(self) -> bytes: ...

    def stored_size(self, name: str) -> int:
        """The bytes the image ``name`` takes where it is stored (for progress)."""

    def read(self, name: str, cap: int, chunk_bytes: int, progress: Callable[[int], None]) -> bytes:
        """The image ``name``'s bytes, refused past ``cap`` bytes; ``progress(stored
        bytes read)`` after each ``chunk_bytes``."""

    def __enter__(self) -> SogSource: ...

    def __exit__(self, *exc) -> None: ...


def open_source(path, shown: str) -> SogSource:
    """The source of the SOG scene at ``path``: a bundled .sog file, an unbundled scene's
    meta.json, or the folder holding it."""
    if os.path.isdir(path):
        path = meta_file(path)
        if not os.path.isfile(path):
            raise file_error(shown, f"folder has no {META_NAME} (an unbundled SOG scene keeps one beside its images)")
    return Bundle(path, shown) if is_bundle(path) else Folder(path, shown)


class Bundle:
    """A zip archive, its members found by the central directory; see :meth:`read`."""

    def __init__(self, path, shown: str) -> None:
        self.shown = shown
        self.shown_meta = f"{shown}: {META_NAME}"
        self.file = open(path, "rb")
        try:
            self.size = os.fstat(self.file.fileno()).st_size
            # zipfile only parses the central directory here; members are read below.
            with zipfile.ZipFile(self.file) as archive:
                infos = archive.infolist()
        except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, ValueError, EOFError,
                struct.error, IndexError, KeyError, OverflowError) as exc:
            self.file.close()
            detail = " ".join(str(exc).split()) or type(exc).__name__
            raise file_error(shown, f"not a readable SOG bundle (zip: {shown_token(detail, 80)[1:-1]})") from None
        except BaseException:
            self.file.close()
            raise
        self.members: dict[str, zipfile.ZipInfo] = {}
        for info in infos:
            self.members.setdefault(info.filename, info)  # the first of a name, as the engine finds it

    def __enter__(self) -> Bundle:
        return self

    def __exit__(self, *exc) -> None:
        self.file.close()

    def read_meta(self) -> bytes:
        if META_NAME not in self.members:
            raise file_error(self.shown, f"no {META_NAME} at the root of the archive: not a SOG bundle")
        return self.read(META_NAME, MAX_META_BYTES, 1 << 20, lambda n: None)

    def stored_size(self, name: str) -> int:
        return self._member(name).compress_size

    def _member(self, name: str) -> zipfile.ZipInfo:
        info = self.members.get(name)
        if info is None:
            raise file_error(self.shown, f"{name}: missing from the archive (meta.json names it)")
        return info

    def read(self, name: str, cap: int, chunk_bytes: int, progress: Callable[[int], None]) -> bytes:
        """Member ``name``'s bytes. Refused: a declared size over ``cap``; a member that
        inflates past its declared size (stopped one byte past it) or short of it; a CRC
        mismatch; encryption; methods other than stored and deflate."""
        shown = f"{self.shown}: {name}"
        info = self._member(name)
        if info.flag_bits & 0x1:
            raise file_error(shown, "encrypted zip member")
        if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
            raise file_error(shown, f"zip compression method {info.compress_type} (expected stored or deflate)")
        declared = info.file_size
        if declared > cap:
            raise file_error(shown, f"declares {declared} bytes uncompressed, more than this scene can need "
                                    f"({cap}): refused")
        if info.compress_type == zipfile.ZIP_STORED and info.compress_size != declared:
            raise file_error(shown, f"stored zip member of {info.compress_size} bytes declares {declared}")
        self.file.seek(self._data_offset(shown, info))
        out = self._inflate(shown, info, chunk_bytes, progress)
        if len(out) != declared:
            raise file_error(shown, f"holds {len(out)} bytes but declares {declared} (corrupt archive)")
        if zlib.crc32(out) != info.CRC:
            raise file_error(shown, "CRC mismatch (corrupt archive)")
        return bytes(out)

    def _data_offset(self, shown: str, info: zipfile.ZipInfo) -> int:
        """Where the member's data starts: after its local header, which the central
        directory does not describe."""
        if info.header_offset < 0:  # zipfile shifts offsets by what precedes the archive
            raise file_error(shown, "zip member starts before the file (corrupt archive)")
        self.file.seek(info.header_offset)
        local = self.file.read(30)
        if len(local) < 30 or local[:4] != _ZIP_MAGIC:
            raise file_error(shown, "bad zip local header (corrupt archive)")
        name_length, extra_length = struct.unpack("<HH", local[26:30])
        start = info.header_offset + 30 + name_length + extra_length
        if start + info.compress_size > self.size:
            raise file_error(shown, "zip member extends past the end of the file (truncated archive)")
        return start

    def _inflate(self, shown: str, info: zipfile.ZipInfo, chunk_bytes: int,
                 progress: Callable[[int], None]) -> bytearray:
        """The member's data, read from the file's position, never more than one byte past
        its declared size."""
        declared = info.file_size
        out = bytearray()
        inflate = zlib.decompressobj(-zlib.MAX_WBITS) if info.compress_type == zipfile.ZIP_DEFLATED else None
        left = info.compress_size
        try:
            while left:
                chunk = self.file.read(min(left, chunk_bytes))
                if not chunk:
                    raise file_error(shown, "truncated zip member (the file shrank while reading)")
                left -= len(chunk)
                if inflate is None:
                    out += chunk
                else:
                    while chunk and not inflate.eof:
                        out += inflate.decompress(chunk, declared + 1 - len(out))
                        if len(out) > declared:
                            raise file_error(shown, f"inflates to more than its declared {declared} bytes: refused")
                        chunk = inflate.unconsumed_tail
                progress(info.compress_size - left)
        except zlib.error as exc:
            raise file_error(shown, f"corrupt deflate data ({exc})") from None
        if inflate is not None and not inflate.eof:
            raise file_error(shown, "truncated deflate data (corrupt archive)")
        return out


class Folder:
    """An unbundled scene: meta.json and the images it names, all inside its folder."""

    def __init__(self, meta_path, shown: str) -> None:
        self.shown = shown
        self.shown_meta = shown
        self.meta_path = meta_path
        self.folder = os.path.dirname(os.path.abspath(meta_path))
        self.real_folder = os.path.realpath(self.folder)

    def __enter__(self) -> Folder:
        return self

    def __exit__(self, *exc) -> None:
        pass

    def read_meta(self) -> bytes:
        size = os.path.getsize(self.meta_path)
        if size > MAX_META_BYTES:
            raise file_error(self.shown, f"{size} bytes: too big for a SOG meta.json (at most {MAX_META_BYTES})")
        with open(self.meta_path, "rb") as f:
            return f.read(MAX_META_BYTES + 1)

    def resolve(self, name: str) -> str:
        """The path of the image ``name``; refused when it lies outside the folder."""
        parts = name.replace("\\", "/").split("/")
        outside = os.path.isabs(name) or ".." in parts or "\x00" in name
        if not outside:
            target = os.path.realpath(os.path.join(self.folder, name))
            outside = os.path.commonpath([target, self.real_folder]) != self.real_folder
        if outside:
            raise file_error(self.shown, f"image {shown_token(name)} lies outside the scene's folder: refused")
        return target

    def stored_size(self, name: str) -> int:
        target = self.resolve(name)
        try:
            return os.path.getsize(target)
        except OSError:
            raise file_error(self.shown, f"{name}: no such file beside {os.path.basename(self.meta_path)} "
                                         "(meta.json names it)") from None

    def read(self, name: str, cap: int, chunk_bytes: int, progress: Callable[[int], None]) -> bytes:
        shown = f"{self.shown}: {name}"
        target = self.resolve(name)
        try:
            with open(target, "rb") as f:
                size = os.fstat(f.fileno()).st_size
                if size > cap:
                    raise file_error(shown, f"{size} bytes, more than this scene can need ({cap}): refused")
                out = bytearray()
                while len(out) < size:
                    chunk = f.read(min(chunk_bytes, size - len(out)))
                    if not chunk:
                        raise file_error(shown, "truncated (the file shrank while reading)")
                    out += chunk
                    progress(len(out))
        except OSError as exc:
            raise file_error(shown, f"cannot read: {exc.strerror or exc}") from None
        return bytes(out)

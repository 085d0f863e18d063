"""The bytes of a ``.spz`` file around its gaussians: the header, the optional extension
records, and the compressed arrays (one gzip stream for versions 1-3, a table of
contents and zstd streams for version 4), read with every size bounded before it is
allocated; and the same container written around encoded arrays. The layout is in
:mod:`~raygs_viewer.scene.spz_format`.
"""

from __future__ import annotations

import gzip
import io
import os
import struct
import zlib

import numpy as np
import zstandard

from raygs_viewer.scene.progress import Reporter
from raygs_viewer.scene.reading import file_error
from raygs_viewer.scene.spz_format import COORDINATE_SYSTEMS, LATEST_VERSION, SPZ_MAGIC, Layout

GZIP_MAGIC = b"\x1f\x8b"
#: More gaussians than any shared scene holds (the largest are a few tens of millions);
#: a header declaring more is corrupt or hostile.
MAX_POINTS = 100_000_000
#: Extension records (a coordinate system, camera limits) are a few dozen bytes.
MAX_EXTENSION_BYTES = 1 << 20
#: Deflate cannot expand more than 1032:1 (a 258-byte match coded in 2 bits).
_GZIP_MAX_RATIO = 1032
#: The owners' v4 sanity bound: numPoints * 9 <= file size * 1024.
_ZSTD_MAX_RATIO = 1024
_ZSTD_MIN_BYTES_PER_POINT = 9
_FLAG_EXTENSIONS = 0x2
_EXT_COORDINATE_SYSTEM = 0xADBE0003
_LEGACY_HEADER = struct.Struct("<IIIBBBB")
_NGSP_HEADER = struct.Struct("<IIIBBBBI12x")


def read_spz_file(path, shown: str, report: Reporter, chunk: int) -> tuple[Layout, np.ndarray, int]:
    """The header's layout, the packed arrays' bytes (uint8, in the file's order) and the
    coordinate system the file declares they are stored in (an index into
    COORDINATE_SYSTEMS, from 1; 0 when it declares none: the reader's convention decides)."""
    size = os.path.getsize(path)
    with open(path, "rb") as f:
        magic = f.read(4)
        f.seek(0)
        if magic[:2] == GZIP_MAGIC:
            layout, data, extensions = _read_gzip(f, size, shown, report, chunk)
        elif len(magic) == 4 and struct.unpack("<I", magic)[0] == SPZ_MAGIC:
            layout, data, extensions = _read_ngsp(f, size, shown, report, chunk)
        else:
            what = "an empty file" if not magic else "starts with neither gzip's 1f 8b nor 'NGSP'"
            raise file_error(shown, f"not a .spz file ({what})")
    return layout, data, _coordinate_system(extensions, shown)


def _check_header(shown: str, version: int, n: int, degree: int, fractional_bits: int) -> None:
    if version < 1 or version > LATEST_VERSION:
        raise file_error(shown, f"unsupported .spz version {version} (this viewer reads versions 1 to "
                                f"{LATEST_VERSION})")
    if n > MAX_POINTS:
        raise file_error(shown, f"corrupt .spz header: {n:,} gaussians declared (at most {MAX_POINTS:,} "
                                "are accepted)")
    if degree > 4:
        raise file_error(shown, f"corrupt .spz header: SH degree {degree} (expected 0 to 4)")
    # The 24-bit word has a sign bit; more fractional bits than 23 would leave no
    # integer part at all (and the owners' writer always uses 12).
    if version > 1 and fractional_bits > 23:
        raise file_error(shown, f"corrupt .spz header: {fractional_bits} fractional bits (expected 0 to 23)")


def _read_gzip(f, size: int, shown: str, report: Reporter, chunk: int):
    inflater = _Inflater(f, shown, chunk)
    head = inflater.read_exactly(_LEGACY_HEADER.size, "its header")
    magic, version, n, degree, fractional_bits, flags, _ = _LEGACY_HEADER.unpack(head)
    if magic != SPZ_MAGIC:
        raise file_error(shown, "not a .spz file (the gzip stream does not start with 'NGSP')")
    _check_header(shown, version, n, degree, fractional_bits)
    layout = Layout(version, n, degree, fractional_bits, flags)
    total = n * layout.row_bytes
    if _LEGACY_HEADER.size + total > _GZIP_MAX_RATIO * size + 1024:
        raise file_error(shown, f"corrupt .spz header: {n:,} gaussians ({_LEGACY_HEADER.size + total:,} bytes) "
                                f"cannot come out of {size:,} bytes of gzip")
    data = np.empty(total, dtype=np.uint8)
    inflater.read_into(memoryview(data), "the gaussians", lambda done: report.reading(done, total))
    allowed = MAX_EXTENSION_BYTES if flags & _FLAG_EXTENSIONS else 0
    extra = inflater.finish(allowed, _LEGACY_HEADER.size + total)
    return layout, data, _extension_records(extra) if flags & _FLAG_EXTENSIONS else {}


class _Inflater:
    """A gzip stream read from a file a chunk at a time, never inflating more than asked for."""

    def __init__(self, f, shown: str, chunk: int) -> None:
        self.f, self.shown, self.chunk = f, shown, chunk
        self.z = zlib.decompressobj(16 + zlib.MAX_WBITS)
        self.pending = b""
        self.out = 0

    def _inflate(self, limit: int) -> bytes:
        """Up to ``limit`` (>0) more bytes; b"" only at the end of the stream."""
        while True:
            if self.z.eof:
                return b""
            if not self.pending:
                self.pending = self.z.unconsumed_tail or self.f.read(self.chunk)
                if not self.pending:
                    return b""
            try:
                piece = self.z.decompress(self.pending, limit)
            except zlib.error as exc:
                raise file_error(self.shown, f"corrupt .spz: the gzip data is damaged ({exc})") from None
            self.pending = self.z.unconsumed_tail
            if piece:
                self.out += len(piece)
                return piece

    def read_into(self, view: memoryview, what: str, progress=None) -> None:
        done = 0
        while done < len(view):
            piece = self._inflate(min(len(view) - done, self.chunk))
            if not piece:
                self._ended_early(what)
            view[done: done + len(piece)] = piece
            done += len(piece)
            if progress is not None:
                progress(done)

    def read_exactly(self, count: int, what: str) -> bytes:
        buffer = bytearray(count)
        self.read_into(memoryview(buffer), what)
        return bytes(buffer)

    def _ended_early(self, what: str):
        if self.z.eof:
            raise file_error(self.shown, f"corrupt .spz: the data ends inside {what} (after {self.out:,} bytes)")
        raise file_error(self.shown, f"truncated .spz: the gzip stream is cut off inside {what}")

    def finish(self, allowed: int, expected: int) -> bytes:
        """Up to ``allowed`` trailing bytes, then the end of the stream (checksum checked)."""
        extra = bytearray()
        while True:
            piece = self._inflate(allowed - len(extra) + 1)
            if not piece:
                break
            extra += piece
            if len(extra) > allowed:
                raise file_error(self.shown, f"corrupt .spz: the data runs past the {expected:,} bytes its "
                                             "header declares")
        if not self.z.eof:
            raise file_error(self.shown, "truncated .spz: the gzip stream is cut off at its end")
        return bytes(extra)


def _read_ngsp(f, size: int, shown: str, report: Reporter, chunk: int):
    head = f.read(_NGSP_HEADER.size)
    if len(head) < _NGSP_HEADER.size:
        raise file_error(shown, f"truncated .spz: {size} bytes, less than the 32-byte version 4 header")
    magic, version, n, degree, fractional_bits, flags, streams, toc = _NGSP_HEADER.unpack(head)
    if 1 <= version < 4:
        raise file_error(shown, f"corrupt .spz: version {version} files are gzip-compressed, this one is not")
    _check_header(shown, version, n, degree, fractional_bits)
    layout = Layout(version, n, degree, fractional_bits, flags)
    if n * _ZSTD_MIN_BYTES_PER_POINT > _ZSTD_MAX_RATIO * size:
        raise file_error(shown, f"corrupt .spz header: {n:,} gaussians cannot come out of a {size:,}-byte file")
    sizes = [s for s in layout.sizes if s]
    if streams != len(sizes):
        raise file_error(shown, f"corrupt .spz header: {streams} streams, expected {len(sizes)} for "
                                f"{n:,} gaussians of SH degree {degree}")
    toc_end = toc + 16 * streams
    if toc < _NGSP_HEADER.size or toc_end > size:
        raise file_error(shown, f"corrupt .spz: the table of contents (bytes {toc:,} to {toc_end:,}) lies "
                                f"outside the file's {size:,} bytes")
    extensions = {}
    if flags & _FLAG_EXTENSIONS and toc > _NGSP_HEADER.size:
        if toc - _NGSP_HEADER.size > MAX_EXTENSION_BYTES:
            raise file_error(shown, f"corrupt .spz: {toc - _NGSP_HEADER.size:,} bytes of extensions")
        extensions = _extension_records(f.read(toc - _NGSP_HEADER.size))
    f.seek(toc)
    entries = np.frombuffer(f.read(16 * streams), dtype="<u8").reshape(streams, 2).astype(object)
    offset = toc_end
    for index, ((packed, unpacked), expected) in enumerate(zip(entries, sizes)):
        if unpacked != expected:
            raise file_error(shown, f"corrupt .spz: stream {index} declares {unpacked:,} bytes, the header "
                                    f"implies {expected:,}")
        offset += packed
    if offset != size:
        raise file_error(shown, f"corrupt .spz: the table of contents accounts for {offset:,} bytes, the file "
                                f"has {size:,}")
    total = sum(sizes)
    data = np.empty(total, dtype=np.uint8)
    view = memoryview(data)
    decompressor = zstandard.ZstdDecompressor()
    f.seek(toc_end)
    done = 0
    for index, (packed, unpacked) in enumerate(entries):
        source = _Window(f, int(packed))
        begin, end = done, done + int(unpacked)
        try:
            reader = decompressor.stream_reader(source, read_size=chunk, read_across_frames=True, closefd=False)
            while done < end:
                piece = reader.read(min(end - done, chunk))
                if not piece:
                    raise file_error(shown, f"truncated .spz: stream {index} ends after {done - begin:,} "
                                            f"of its {unpacked:,} bytes")
                view[done: done + len(piece)] = piece
                done += len(piece)
                report.reading(done, total)
            if reader.read(1):
                raise file_error(shown, f"corrupt .spz: stream {index} holds more than the {unpacked:,} bytes "
                                        "its table of contents declares")
        except zstandard.ZstdError as exc:
            raise file_error(shown, f"corrupt .spz: stream {index}: {exc}") from None
    return layout, data, extensions


class _Window(io.RawIOBase):
    """``count`` bytes of a file from its current position, as a stream of their own."""

    def __init__(self, f, count: int) -> None:
        self.f, self.left = f, count

    def readable(self) -> bool:
        return True

    def readinto(self, buffer) -> int:
        want = min(len(buffer), self.left)
        got = self.f.readinto(memoryview(buffer)[:want]) if want else 0
        self.left -= got
        return got


def _extension_records(data: bytes) -> dict[int, bytes]:
    """type -> payload of the owners' ``[u32 type][u32 byteLength][payload]`` records; a
    record cut short ends the list, as in the owners' reader."""
    records, pos = {}, 0
    while pos + 8 <= len(data):
        kind, length = struct.unpack_from("<II", data, pos)
        if length > len(data) - pos - 8:
            break
        records.setdefault(kind, data[pos + 8: pos + 8 + length])
        pos += 8 + length
    return records


def _coordinate_system(extensions: dict[int, bytes], shown: str) -> int:
    payload = extensions.get(_EXT_COORDINATE_SYSTEM)
    if payload is None or len(payload) < 4:
        return 0
    system = struct.unpack_from("<I", payload)[0]
    if system == 0:  # UNSPECIFIED declares nothing: the reader's convention decides, as without the extension
        return 0
    if system > len(COORDINATE_SYSTEMS):
        raise file_error(shown, f"corrupt .spz: unknown coordinate system {system} in its extension")
    if system > 8:
        raise file_error(shown, f"this .spz stores its gaussians in the {COORDINATE_SYSTEMS[system - 1]} "
                                "coordinate system, which needs an SH rotation this viewer does not do (RUB and "
                                "the other axis-flipped systems are read)")
    return system


def pack_spz_file(version: int, n: int, degree: int, fractional_bits: int, arrays: list[bytes]) -> bytes:
    """The whole file around the packed arrays (in the file's order): version 2 or 3 as
    one gzip stream, version 4 as zstd streams, compressed as the owners' writer does."""
    if version < 4:
        header = _LEGACY_HEADER.pack(SPZ_MAGIC, version, n, degree, fractional_bits, 0, 0)
        return gzip.compress(header + b"".join(arrays), compresslevel=6, mtime=0)
    streams = [zstandard.ZstdCompressor(level=12).compress(a) for a in arrays if a]
    header = _NGSP_HEADER.pack(SPZ_MAGIC, version, n, degree, fractional_bits, 0, len(streams), _NGSP_HEADER.size)
    toc = b"".join(struct.pack("<QQ", len(s), len(a)) for s, a in zip(streams, [a for a in arrays if a]))
    return header + toc + b"".join(streams)

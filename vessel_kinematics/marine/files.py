"""
A log file opened for reading: as it is, or gzip-compressed (told by its content, not its name).

Long logs are often kept gzipped (``candump -l | gzip``, a logger's rotated files). A gzip file
cut short (copied while its logger still wrote it) reads up to where it ends, as a plain log
cut short does; so does a corrupt one, up to the damage.
"""

from __future__ import annotations

import gzip
from pathlib import Path
from typing import BinaryIO, Iterator
import zlib

__all__ = ['chunks', 'GZIP_MAGIC', 'open_read', 'TRUNCATED']

#: How a gzip file starts (RFC 1952).
GZIP_MAGIC = b'\x1f\x8b'
#: zlib's window bits for a gzip stream (RFC 1952 header and trailer).
_GZIP_WBITS = 16 + zlib.MAX_WBITS
#: What reading a gzip file cut short or damaged raises (:func:`open_read`'s).
TRUNCATED = (EOFError, zlib.error, gzip.BadGzipFile)


def open_read(path: str | Path) -> BinaryIO:
    """Return ``path`` opened for binary reading, decompressed when it is gzip."""
    f = open(path, 'rb')
    if f.read(2) != GZIP_MAGIC:
        f.seek(0)
        return f
    f.close()
    return gzip.open(path, 'rb')  # type: ignore[return-value]


def chunks(path: str | Path, size: int = 1 << 16) -> Iterator[bytes]:
    """
    Yield the content of ``path`` (decompressed) in blocks of about ``size``, up to its end.

    A gzip file is decompressed as it streams (every member of one written in parts), so a
    file cut short yields all it holds, up to the last byte that decompresses.
    """
    with open(path, 'rb') as f:
        data = f.read(size)
        if not data.startswith(GZIP_MAGIC):
            while data:
                yield data
                data = f.read(size)
            return
        inflate = zlib.decompressobj(wbits=_GZIP_WBITS)
        while data:
            while data:
                try:
                    out = inflate.decompress(data)
                except zlib.error:
                    return
                if out:
                    yield out
                data = b''
                if inflate.eof and inflate.unused_data:     # the next member
                    data = inflate.unused_data
                    inflate = zlib.decompressobj(wbits=_GZIP_WBITS)
            data = f.read(size)

"""Image bombs for the size-limit tests: small files that declare (and really hold) huge images.

:func:`zero_png` writes a valid 8-bit grey PNG of zero pixels without compressing its pixels row by row: one
block of rows is deflated once with a full flush (which makes the compressed block independent of what came
before), then repeated, and the zlib trailer's Adler-32 is computed over the whole image. A 30,000 x 30,000
PNG (900 MB of pixels) is about 0.9 MB and takes a fraction of a second to build.
"""

from __future__ import annotations

import struct
import zlib

from driftmap.formats.frame_images import PNG_IEND, PNG_MAGIC

_BLOCK_BYTES = 16 * 1024**2  # uncompressed bytes per repeated deflate block
_EMPTY_FINAL_BLOCK = b"\x03\x00"  # a final fixed-Huffman deflate block holding only end-of-block


def _chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def _deflated_zeros(size: int) -> bytes:
    """Raw deflate blocks (no zlib header) of ``size`` zero bytes, ending on a byte boundary, not final."""
    compressor = zlib.compressobj(9)
    return (compressor.compress(bytes(size)) + compressor.flush(zlib.Z_FULL_FLUSH))[2:]


def zero_png(width_px: int, height_px: int) -> bytes:
    """A complete grey 8-bit PNG of ``width_px`` x ``height_px`` zero pixels."""
    row = width_px + 1  # filter byte + pixels
    rows_per_block = max(1, _BLOCK_BYTES // row)
    full, rest = divmod(height_px, rows_per_block)
    block = bytes(row * rows_per_block)
    adler = 1
    for _ in range(full):
        adler = zlib.adler32(block, adler)
    adler = zlib.adler32(bytes(row * rest), adler)
    stream = (
        b"\x78\xda"
        + _deflated_zeros(len(block)) * full
        + (_deflated_zeros(row * rest) if rest else b"")
        + _EMPTY_FINAL_BLOCK
        + struct.pack(">I", adler)
    )
    header = struct.pack(">IIBBBBB", width_px, height_px, 8, 0, 0, 0, 0)
    return PNG_MAGIC + _chunk(b"IHDR", header) + _chunk(b"IDAT", stream) + PNG_IEND

"""Named arrays as ``.npz`` bytes: the format of the blobs a map build hands between processes and keeps."""

from __future__ import annotations

import io
import zipfile
from typing import Any

import numpy as np
from numpy.typing import NDArray

from driftmap.errors import BadInputError

__all__ = ["arrays_bytes", "bytes_arrays"]


def arrays_bytes(arrays: dict[str, NDArray[Any]]) -> bytes:
    """Named arrays as an uncompressed ``.npz`` (thumbnails are noise-like: compression gains little)."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    return buffer.getvalue()


def bytes_arrays(data: bytes, what: str) -> dict[str, NDArray[Any]]:
    """The arrays :func:`arrays_bytes` wrote.

    Raises:
        BadInputError: ``data`` (named ``what`` in the message) is no ``.npz``.
    """
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as arrays:
            return {k: arrays[k] for k in arrays.files}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise BadInputError(f"{what} is not a readable .npz: {exc}") from exc

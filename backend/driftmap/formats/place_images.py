"""Image folders of place-recognition data (``docs/formats.md``): list, decode, check sizes, read gt.

A folder given to ``driftmap vpr match`` (``--db`` or ``--query``) holds images in any of
:data:`driftmap.formats.place_dataset.IMAGE_SUFFIXES`; sorted name order is route (or traversal) order.
Every image of a folder must decode and have the size of the folder's first image.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from driftmap.errors import BadInputError
from driftmap.formats.frame_images import decode_gray
from driftmap.formats.place_dataset import IMAGE_SUFFIXES, parse_gt_csv
from driftmap.formats.tables import decode_text

__all__ = ["find_gt_csv", "gt_matrix", "list_images", "read_gray_stack", "read_gt_pairs"]


def list_images(folder: Path) -> list[Path]:
    """The image files of a folder in sorted name order (hidden files and other suffixes ignored).

    Raises:
        BadInputError: the folder is missing or holds no image.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise BadInputError("folder does not exist" if not folder.exists() else "not a folder", file=folder)
    names = sorted(
        name
        for name in os.listdir(folder)
        if not name.startswith(".")
        and os.path.splitext(name)[1].lower() in IMAGE_SUFFIXES
        and (folder / name).is_file()
    )
    if not names:
        raise BadInputError(f"no images ({', '.join(IMAGE_SUFFIXES)}) in the folder", file=folder)
    return [folder / name for name in names]


def read_gray_stack(files: list[Path]) -> NDArray[np.uint8]:
    """Decode images to one ``(N, H, W)`` uint8 grey stack.

    Raises:
        BadInputError: an unreadable image, or one whose size differs from the first image's (named).
    """
    if not files:
        raise BadInputError("no images to read")
    first: NDArray[np.uint8] | None = None
    out: NDArray[np.uint8] | None = None
    for i, path in enumerate(files):
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise BadInputError(f"cannot read file: {exc.strerror}", file=path) from None
        image = decode_gray(data, path)
        if first is None:
            first = image
            out = np.empty((len(files), *image.shape), dtype=np.uint8)
        elif image.shape != first.shape:
            raise BadInputError(
                f"image is {image.shape[1]}x{image.shape[0]}, the folder's first image "
                f"{files[0].name} is {first.shape[1]}x{first.shape[0]}",
                file=path,
            )
        assert out is not None
        out[i] = image
    assert out is not None
    return out


def find_gt_csv(db_folder: Path, query_folder: Path) -> Path | None:
    """``gt.csv`` of the dataset holding both folders (their common parent), or None when there is none."""
    parent = Path(db_folder).resolve().parent
    if Path(query_folder).resolve().parent != parent:
        return None
    path = parent / "gt.csv"
    return path if path.is_file() else None


def read_gt_pairs(path: Path, query_files: list[Path], db_files: list[Path]) -> list[tuple[str, str]]:
    """The acceptable (query name, db name) pairs of a ``gt.csv``, checked against the images present."""
    try:
        text = decode_text(Path(path).read_bytes(), path)
    except OSError as exc:
        raise BadInputError(f"cannot read file: {exc.strerror}", file=path) from None
    return parse_gt_csv(text, path, {p.name for p in query_files}, {p.name for p in db_files})


def gt_matrix(
    pairs: list[tuple[str, str]], query_files: list[Path], db_files: list[Path]
) -> NDArray[np.bool_]:
    """``(Q, D)`` bool: True where (query i, reference j) is an acceptable pair."""
    q_index = {p.name: i for i, p in enumerate(query_files)}
    d_index = {p.name: j for j, p in enumerate(db_files)}
    gt = np.zeros((len(query_files), len(db_files)), dtype=bool)
    for q, d in pairs:
        gt[q_index[q], d_index[d]] = True
    return gt

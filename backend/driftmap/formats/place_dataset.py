"""A place-recognition dataset folder (``docs/formats.md``)::

    <dataset>/db/      reference images (any names; sorted name order = route order)
    <dataset>/query/   query images
    <dataset>/gt.csv   header ``query,db``: one row per acceptable (query, reference) pair

Images are the files of ``db/`` and ``query/`` with an image extension (case-insensitive); hidden files
and anything else are ignored. Pixels are not checked here; decode with
:func:`driftmap.formats.frame_images.decode_gray`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from driftmap.errors import BadInputError
from driftmap.formats.tables import decode_text, parse_text, read_table, table_text, write_text_atomic

IMAGE_SUFFIXES: tuple[str, ...] = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")
GT_HEADER: tuple[str, ...] = ("query", "db")


@dataclass(frozen=True)
class PlaceDataset:
    """The files of a place-recognition dataset.

    Attributes:
        path: the dataset folder.
        db_files: reference images in sorted name order (= route order).
        query_files: query images in sorted name order.
        gt: acceptable (query file name, db file name) pairs in ``gt.csv`` order; empty without gt.csv.
    """

    path: Path
    db_files: list[Path]
    query_files: list[Path]
    gt: list[tuple[str, str]]


def read_place_dataset(path: Path, *, require_gt: bool = True) -> PlaceDataset:
    """List and validate a place-recognition dataset folder.

    Args:
        path: the dataset folder.
        require_gt: refuse a dataset without ``gt.csv`` (set False to run without evaluation).

    Raises:
        BadInputError: a missing folder, an empty ``db/`` or ``query/``, a missing ``gt.csv`` when
            required, or a ``gt.csv`` row that is malformed, repeated or names an image that is not there.
    """
    path = Path(path)
    if not path.is_dir():
        raise BadInputError(
            "dataset folder does not exist" if not path.exists() else "not a folder", file=path
        )
    db_files = _images(path / "db")
    query_files = _images(path / "query")
    gt_csv = path / "gt.csv"
    gt: list[tuple[str, str]] = []
    if gt_csv.exists():
        try:
            text = decode_text(gt_csv.read_bytes(), gt_csv)
        except OSError as exc:
            raise BadInputError(f"cannot read file: {exc.strerror}", file=gt_csv) from None
        gt = parse_gt_csv(text, gt_csv, {p.name for p in query_files}, {p.name for p in db_files})
    elif require_gt:
        raise BadInputError("gt.csv is missing", file=gt_csv)
    return PlaceDataset(path=path, db_files=db_files, query_files=query_files, gt=gt)


def parse_gt_csv(text: str, file: str | Path, queries: set[str], dbs: set[str]) -> list[tuple[str, str]]:
    """Parse ``gt.csv`` text, checking every name against the images present.

    Args:
        text: the file's text.
        file: the file name used in error messages.
        queries: the file names in ``query/``.
        dbs: the file names in ``db/``.

    Returns:
        (query name, db name) pairs in file order.
    """
    _, table = read_table(text, file, [GT_HEADER])
    pairs: list[tuple[str, str]] = []
    seen: dict[tuple[str, str], int] = {}
    for row in table:
        query = parse_text(row.cells["query"], file=file, line=row.line, field="query")
        db = parse_text(row.cells["db"], file=file, line=row.line, field="db")
        if query not in queries:
            raise BadInputError(f"no image {query!r} in query/", file=file, line=row.line, field="query")
        if db not in dbs:
            raise BadInputError(f"no image {db!r} in db/", file=file, line=row.line, field="db")
        if (query, db) in seen:
            raise BadInputError(
                f"pair appears twice (first on line {seen[(query, db)]})",
                file=file,
                line=row.line,
                field="db",
            )
        seen[(query, db)] = row.line
        pairs.append((query, db))
    return pairs


def write_gt_csv(path: Path, pairs: list[tuple[str, str]]) -> None:
    """Write ``gt.csv`` atomically (used by tests and the simulator's dataset export)."""
    write_text_atomic(path, table_text(GT_HEADER, [[q, d] for q, d in pairs]))


def _images(folder: Path) -> list[Path]:
    if not folder.is_dir():
        raise BadInputError(f"the {folder.name}/ folder is missing", file=folder)
    names = sorted(
        name
        for name in os.listdir(folder)
        if not name.startswith(".")
        and os.path.splitext(name)[1].lower() in IMAGE_SUFFIXES
        and (folder / name).is_file()
    )
    if not names:
        raise BadInputError(f"no images ({', '.join(IMAGE_SUFFIXES)}) in {folder.name}/", file=folder)
    return [folder / name for name in names]

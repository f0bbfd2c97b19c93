"""``driftmap vpr``: place recognition on outside image folders (single-image SAD/SESAME or the route HMM)."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Literal

import typer
from rich.table import Table

from driftmap.cli.common import console, user_errors
from driftmap.core.place_recognition import metrics
from driftmap.core.place_recognition.route import recognise_places
from driftmap.core.place_recognition.route_filter import ROUTE_ANY_SPEED, ROUTE_DEFAULT, RouteParams
from driftmap.core.place_recognition.single import METHODS, VPR_PRESETS, VprMethod
from driftmap.errors import BadInputError
from driftmap.formats.csv_exports import PlaceMatchRow, write_place_matches_csv
from driftmap.formats.place_images import find_gt_csv, gt_matrix, list_images, read_gray_stack, read_gt_pairs

vpr_app = typer.Typer(help="Place recognition on outside datasets (formats.md).", no_args_is_help=True)


def _method(name: str) -> VprMethod:
    """The method of that name (``--method``)."""
    for method in METHODS:
        if method == name:
            return method
    raise BadInputError(f"unknown method {name!r}; choose {', '.join(METHODS)}", field="--method")


def _route(any_speed: bool, online: bool) -> RouteParams:
    """The route HMM of ``--any-speed`` / ``--online``."""
    route = ROUTE_ANY_SPEED if any_speed else ROUTE_DEFAULT
    return replace(route, smooth=False) if online else route


@vpr_app.command("match")
def vpr_match(
    db: Annotated[Path, typer.Option("--db", help="Folder of reference images (sorted name = route order).")],
    query: Annotated[Path, typer.Option("--query", help="Folder of query images (sorted name order).")],
    out: Annotated[Path, typer.Option("--out", help="CSV to write (query,db,score), one row per query.")],
    method: Annotated[
        Literal["sad", "sesame"] | None,
        typer.Option(
            help="sad (patch-normalised SAD) or sesame (the SESAME paper); default sad with --temporal, else sesame."
        ),
    ] = None,
    temporal: Annotated[
        bool, typer.Option("--temporal", help="HMM over the references as an ordered route.")
    ] = False,
    preset: Annotated[
        Literal["mine", "route"] | None,
        typer.Option(
            help="mine (shift search +-4/+-2 px) or route (camera on a fixed path, no shifts); default route"
            " with --temporal, else mine."
        ),
    ] = None,
    any_speed: Annotated[
        bool,
        typer.Option(
            "--any-speed",
            help="With --temporal: track the query's speed (0-3x the references') instead of ~1x.",
        ),
    ] = False,
    online: Annotated[
        bool,
        typer.Option(
            "--online",
            help="With --temporal: the causal filter (each match from the frames up to it, as a vehicle"
            " live) instead of the posterior given every query frame.",
        ),
    ] = False,
    gt: Annotated[
        Path | None, typer.Option("--gt", help="gt.csv to score against (default: the dataset's, if any).")
    ] = None,
    workers: Annotated[int, typer.Option(min=1, help="Threads computing image distances.")] = 1,
) -> None:
    """Match every query image to a reference image; print recall@1, AUC and recall at 100% precision
    when ground truth is available."""
    with user_errors():
        vpr_method = _method(method if method is not None else ("sad" if temporal else "sesame"))
        preset = preset if preset is not None else ("route" if temporal else "mine")
        if (any_speed or online) and not temporal:
            raise BadInputError("needs --temporal", field="--any-speed" if any_speed else "--online")
        if preset not in VPR_PRESETS:
            raise BadInputError(
                f"unknown preset {preset!r}; choose {', '.join(VPR_PRESETS)}", field="--preset"
            )
        db_files, query_files = list_images(db), list_images(query)
        gt_path = gt if gt is not None else find_gt_csv(db, query)
        pairs = read_gt_pairs(gt_path, query_files, db_files) if gt_path is not None else None
        db_images, query_images = read_gray_stack(db_files), read_gray_stack(query_files)
        t0 = time.perf_counter()
        matches = recognise_places(
            query_images,
            db_images,
            vpr_method,
            temporal=temporal,
            params=VPR_PRESETS[preset],
            route=_route(any_speed, online),
            workers=workers,
        )
        seconds = time.perf_counter() - t0
        rows = [
            PlaceMatchRow(q.name, db_files[int(j)].name, float(s))
            for q, j, s in zip(query_files, matches.db_index, matches.score, strict=True)
        ]
        write_place_matches_csv(out, rows)
        result = None
        if pairs is not None:
            gt_table = gt_matrix(pairs, query_files, db_files)
            result, _ = metrics.evaluate_matches(matches.db_index, matches.score, gt_table)
    mode = "single image"
    if temporal:
        mode = ("route HMM, online" if online else "route HMM") + (", any speed" if any_speed else "")
    console.print(
        f"wrote {len(rows)} matches to {out} ({vpr_method}, {mode}, preset {preset}; "
        f"{len(query_files)} queries x {len(db_files)} references in {seconds:.1f} s)"
    )
    if result is not None:
        console.print(f"scored against {gt_path}")
        table = Table("recall@1", "AUC", "recall at 100% precision", "recallable queries")
        table.add_row(
            f"{result.recall_at_1:.3f}",
            f"{result.auc:.3f}",
            f"{result.recall_at_full_precision:.3f}",
            f"{result.recallable} of {result.queries}",
        )
        console.print(table)

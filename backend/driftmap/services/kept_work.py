"""What a map build keeps for the next build of its site, and the figures of what it reused.

A build's stage-1 pieces (:mod:`driftmap.services.map_pieces`), its loop-closure search
(:mod:`driftmap.services.loop_searches`) and its SESAME database's pair scores
(:mod:`driftmap.services.database_scores`) are kept once its map is solved; the CLI's build
(:func:`driftmap.services.maps.build_site_map`) and the job's (:mod:`driftmap.jobs.map_tasks`) both end with
:func:`solve_and_keep`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from sqlalchemy.orm import Session

from driftmap.core.mapping.pipeline import MapBuild, MappingDrive, MappingParams, PreparedDrives, solve_map
from driftmap.core.types import ProgressFn
from driftmap.services import database_scores, loop_searches, map_pieces
from driftmap.store.blobs import BlobBatch, BlobStore
from driftmap.store.models import Site

__all__ = ["KeptWork", "reuse_stats", "solve_and_keep"]


@dataclass(frozen=True)
class KeptWork:
    """What a build prepared and searched, to keep for the next build of its site.

    Attributes:
        chains: each drive's chain key (:func:`driftmap.services.loop_searches.chain_keys`).
        drive_ids: the drives, in build order.
        segments: every segment's ``(drive id, span, piece key, blob sha256)``.
        reused: how many of ``segments`` were loaded, not prepared.
        search: the loop-closure plan and the blocks this build scored (None without loop closures).
    """

    chains: list[str]
    drive_ids: list[int]
    segments: list[tuple[int, tuple[int, int], str, str]]
    reused: int
    search: tuple[loop_searches.LoopPlan, list[loop_searches.ScoredBlock]] | None


def solve_and_keep(
    session: Session,
    blobs: BlobStore,
    batch: BlobBatch,
    site: Site,
    inputs: Sequence[MappingDrive],
    prepared: PreparedDrives,
    params: MappingParams,
    kept: KeptWork,
    progress: ProgressFn | None = None,
    full: bool = False,
) -> tuple[MapBuild, set[str]]:
    """Stages 4-5 of a build of ``site``'s drives ``inputs`` (:func:`~driftmap.core.mapping.pipeline.solve_map`, the SESAME
    database looking up the pair scores the site's last build kept unless ``full``), then keep its pieces,
    loop-closure search and pair scores for the next build. Returns the build, with its reuse figures in its
    stats, and the blobs it no longer holds (for :func:`driftmap.services.map_pieces.drop_stale`)."""
    counts = [d.n_frames for d in inputs]
    known = database_scores.load_scores(session, blobs, site.id, kept.chains, counts, params, full)
    build = solve_map(prepared, inputs, params, progress, known)
    queries = (kept.search[0].queries_kept, kept.search[0].search.n) if kept.search else (0, 0)
    build.stats.update(reuse_stats(kept.reused, len(kept.segments), queries))
    dropped = map_pieces.keep_pieces(session, kept.drive_ids, kept.segments)
    if kept.search is not None:
        dropped |= loop_searches.keep_search(session, site.id, params, kept.chains, *kept.search)
    if build.database_scores is not None:
        scores = build.database_scores
        dropped |= database_scores.keep_scores(session, batch, site.id, kept.chains, counts, scores, params)
    return build, dropped


def reuse_stats(reused: int, segments: int, queries: tuple[int, int] = (0, 0)) -> dict[str, float | int]:
    """The figures of a version saying what its build reused of earlier builds: drive segments (of
    ``segments``) and loop-closure queries (kept, of all)."""
    kept, total = queries
    return {
        "segments_reused": reused,
        "segments_prepared": segments - reused,
        "loop_queries_reused": kept,
        "loop_queries_scored": total - kept,
    }

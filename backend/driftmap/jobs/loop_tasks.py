"""A map build's loop-closure search as ``map.loops`` subtasks, one per block of query keyframes.

After the drives' odometry (``map.drive`` subtasks), the ``map.build`` parent plans the search once,
resuming the site's kept search where its first chains allow (:func:`driftmap.services.loop_searches.plan_loops`),
stores the plan as a blob and queues one ``map.loops`` job per block of about
:data:`~driftmap.services.loop_searches.QUERIES_PER_BLOCK` query keyframes still to score (args ``search_sha256``,
``q0``, ``q1``, ``preset``). Any worker, the waiting parent included (:mod:`driftmap.jobs.subtasks`), scores a
block and stores its scores as a blob. The parent then decides the closures query by query
(:func:`driftmap.core.loop_closure.search.decide_loops`): the same closures as one process's search, whatever
the split and whoever ran it. The blocks' scores become the site's kept search when the version is stored;
the plan blob is dropped. A re-run of the parent plans again (the same blocks) and reuses the subtasks
already finished.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

from driftmap.core.loop_closure.blocks import LoopSearch, QueryScores, score_queries
from driftmap.core.loop_closure.search import LoopMatch
from driftmap.core.mapping.drive import PreparedDrive
from driftmap.core.mapping.prepare import MappingDrive, MappingParams, loop_inputs
from driftmap.errors import ConflictError, NotFoundError
from driftmap.jobs.presets import preset_params
from driftmap.jobs.runtime import JobContext
from driftmap.jobs.subtasks import await_subtasks, existing_subtasks, submit_subtasks
from driftmap.services import loop_searches
from driftmap.store.npz import arrays_bytes, bytes_arrays

KIND = "map.loops"


def _blob(ctx: JobContext, sha: str, what: str) -> bytes:
    if not ctx.runtime.storage.blobs.exists(sha):
        raise NotFoundError(f"job {ctx.job.id}: {what} (blob {sha}) is gone")
    return ctx.runtime.storage.blobs.get(sha)


def map_loops(ctx: JobContext) -> None:
    """Score one block of a build's loop-closure search. Args: ``search_sha256``, ``q0``, ``q1``, ``preset``."""
    _name, params = preset_params(ctx.args)
    ctx.report("loop closure", 0.0)
    sha = str(ctx.args["search_sha256"])
    search = LoopSearch.from_arrays(bytes_arrays(_blob(ctx, sha, "the loop-closure plan"), f"blob {sha}"))
    scores = score_queries(search, params.loops, int(ctx.args["q0"]), int(ctx.args["q1"]))
    data = arrays_bytes(scores.to_arrays())
    with ctx.runtime.storage.blobs.batch() as batch, ctx.runtime.storage.db.session() as session:
        ctx.succeed(session, {"scores_sha256": batch.put(data), "queries_checked": int(scores.checked.sum())})


def find_loops(
    ctx: JobContext,
    site_id: int,
    pieces: Sequence[PreparedDrive],
    drives: Sequence[MappingDrive],
    params: MappingParams,
    chains: Sequence[str],
    full: bool = False,
) -> tuple[tuple[LoopMatch, ...], float, FoundLoops | None]:
    """The closures of the build's keyframes, the site's kept search resumed, the rest searched in ``map.loops``
    subtasks.

    Args:
        ctx: the build.
        site_id: its site.
        pieces: its drives' stage-1 pieces.
        drives: its drives.
        params: its parameters.
        chains: its chain keys (:func:`driftmap.services.loop_searches.chain_keys`).
        full: search afresh whatever the site kept.

    Returns:
        (closures, wall seconds, the search to keep with the blob to drop once stored: the plan the subtasks
        read, if any had anything to score; None when no keyframe has an eligible earlier one).

    Raises:
        DriftmapError: a subtask failed; NotFoundError: a plan or scores blob of an earlier run is gone.
        JobCancelled: the build or a subtask was cancelled.
        ConflictError: a re-run planned other query blocks than the first run.
    """
    start = time.monotonic()
    ctx.report("loop closure", 0.0)
    _keyframes, key_thumbs, key_times = loop_inputs(pieces, drives, params)
    storage = ctx.runtime.storage
    with storage.blobs.batch() as batch, storage.db.session() as session:
        plan = loop_searches.plan_loops(
            session, storage.blobs, batch, site_id, (chains, key_thumbs, key_times), params, full
        )
    if plan is None:  # no keyframe has an eligible earlier one
        return (), time.monotonic() - start, None
    earlier = existing_subtasks(ctx, KIND)
    # With every query's scores kept there is nothing to score and no plan (the frames of every keyframe) to
    # hand over.
    sha: str | None = None
    ids: list[int] = []
    if plan.ranges and earlier:  # a re-run: the blocks of the first run, which may be scored already
        if [(int(a["q0"]), int(a["q1"])) for _i, a in earlier] != plan.ranges:
            raise ConflictError(
                f"job {ctx.job.id}: the loop-closure search planned other blocks than its first run"
            )
        sha = str(earlier[0][1]["search_sha256"])
        ids = [job_id for job_id, _args in earlier]
    elif plan.ranges:
        with storage.blobs.batch() as batch:
            sha = batch.put(arrays_bytes(plan.search.to_arrays()))
        preset = str(ctx.args.get("preset", "paper"))
        args = [{"search_sha256": sha, "q0": q0, "q1": q1, "preset": preset} for q0, q1 in plan.ranges]
        ids = submit_subtasks(ctx, KIND, args)
    results = await_subtasks(ctx, ids, "loop closure", map_loops)
    shas = [str(r["scores_sha256"]) for r in results]
    scored = [
        (
            QueryScores.from_arrays(
                bytes_arrays(_blob(ctx, s, "a block's loop-closure scores"), f"blob {s}")
            ),
            s,
        )
        for s in shas
    ]
    found = loop_searches.decide(plan, params, scored)
    return tuple(found.closures), time.monotonic() - start, FoundLoops(plan, scored, sha)


@dataclass(frozen=True)
class FoundLoops:
    """A build's search: to keep (:func:`driftmap.services.loop_searches.keep_search`) once the version is
    stored, with ``plan_sha256``, the plan the subtasks read, to drop then."""

    plan: loop_searches.LoopPlan
    scored: list[loop_searches.ScoredBlock]
    plan_sha256: str | None

"""A map build's loop-closure search as ``map.loops`` subtasks, one per block of query keyframes.

After the drives' odometry (``map.drive`` subtasks), the ``map.build`` parent plans the search once
(:func:`driftmap.core.loop_closure.blocks.plan_search`: descriptors, background, thresholds), stores the plan as a
blob and queues one ``map.loops`` job per block of about :data:`QUERIES_PER_TASK` query keyframes (args
``search_sha256``, ``q0``, ``q1``, ``preset``). Any worker, the waiting parent included
(:mod:`driftmap.jobs.subtasks`), scores a block and stores its scores as a blob. The parent then decides
the closures query by query (:func:`driftmap.core.loop_closure.search.decide_loops`): the same closures as one
process's search, whatever the split and whoever ran it. A re-run of the parent reuses its plan and the
blocks already scored.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

from driftmap.core.loop_closure.blocks import (
    LoopSearch,
    QueryScores,
    plan_search,
    score_queries,
    split_queries,
)
from driftmap.core.loop_closure.search import LoopMatch, decide_loops
from driftmap.core.mapping.drive import PreparedDrive
from driftmap.core.mapping.prepare import MappingDrive, MappingParams, loop_inputs
from driftmap.errors import NotFoundError
from driftmap.jobs.presets import preset_params
from driftmap.jobs.runtime import JobContext
from driftmap.jobs.subtasks import await_subtasks, existing_subtasks, submit_subtasks
from driftmap.services.map_drives import arrays_bytes, bytes_arrays

KIND = "map.loops"
QUERIES_PER_TASK = 1024
"""Query keyframes per ``map.loops`` subtask (whole blocks of 256: a few seconds each on a medium site)."""


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
    pieces: Sequence[PreparedDrive],
    drives: Sequence[MappingDrive],
    params: MappingParams,
) -> tuple[tuple[LoopMatch, ...], float, list[str]]:
    """The closures of the build's keyframes, searched in ``map.loops`` subtasks.

    Returns:
        (closures, wall seconds, the blobs handed over: the plan and the blocks' scores, to drop once stored).

    Raises:
        DriftmapError: a subtask failed; NotFoundError: a plan or scores blob of an earlier run is gone.
        JobCancelled: the build or a subtask was cancelled.
    """
    start = time.monotonic()
    earlier = existing_subtasks(ctx, KIND)
    if earlier:  # a re-run: the plan of the first run, whose blocks may be scored already
        sha = str(earlier[0][1]["search_sha256"])
        search = LoopSearch.from_arrays(bytes_arrays(_blob(ctx, sha, "the loop-closure plan"), f"blob {sha}"))
        ids = [job_id for job_id, _args in earlier]
    else:
        ctx.report("loop closure", 0.0)
        _keyframes, key_thumbs, key_times = loop_inputs(pieces, drives, params)
        planned = plan_search(key_thumbs, params.loops, key_times)
        if planned is None:  # no keyframe has an eligible earlier one
            return (), time.monotonic() - start, []
        search = planned
        with ctx.runtime.storage.blobs.batch() as batch:
            sha = batch.put(arrays_bytes(search.to_arrays()))
        preset = str(ctx.args.get("preset", "paper"))
        ranges = split_queries(search, params.loops, QUERIES_PER_TASK)
        args = [{"search_sha256": sha, "q0": q0, "q1": q1, "preset": preset} for q0, q1 in ranges]
        ids = submit_subtasks(ctx, KIND, args)
    results = await_subtasks(ctx, ids, "loop closure", map_loops)
    shas = [str(r["scores_sha256"]) for r in results]
    blocks = [
        QueryScores.from_arrays(bytes_arrays(_blob(ctx, s, "a block's loop-closure scores"), f"blob {s}"))
        for s in shas
    ]
    found = decide_loops(search, blocks, params.loops)
    return tuple(found.closures), time.monotonic() - start, [sha, *shas]

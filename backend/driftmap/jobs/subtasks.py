"""A job's subtasks: submitted once, run by any worker or by the waiting parent itself (work stealing).

A parent job (``map.build``) puts its subtasks on the queue (:func:`submit_subtasks`; a re-run of the
parent finds those of its earlier run with :func:`existing_subtasks` and reuses the finished ones), then
:func:`await_subtasks`: it claims and runs, in its own thread, any of them still queued, and otherwise
waits (polling, reporting progress, so that a cancel reaches it) for those other workers took. One worker
therefore finishes alone without deadlock, and every further worker takes subtasks off the queue. A
failed subtask fails the parent (which then cancels the rest, :func:`stop_subtasks`); a cancelled one
cancels it. Subtasks hand their outputs over as blobs named in their results; the parent drops them once
joined (:func:`drop_blobs`).
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Sequence
from typing import Any

from sqlalchemy import select

from driftmap.errors import DriftmapError
from driftmap.jobs.runtime import JobContext, TaskFn, run_job
from driftmap.services import jobs as job_service
from driftmap.store.job_models import Job

log = logging.getLogger(__name__)

POLL_S = 0.5
"""How often a waiting parent looks at its subtasks, seconds."""


def existing_subtasks(ctx: JobContext, kind: str) -> list[tuple[int, dict[str, Any]]]:
    """(id, args) of the parent's subtasks of ``kind`` from an earlier run, oldest first."""
    with ctx.runtime.storage.db.session() as session:
        return [(j.id, dict(j.args)) for j in job_service.children(session, ctx.job.id) if j.kind == kind]


def submit_subtasks(ctx: JobContext, kind: str, args: Sequence[dict[str, Any]]) -> list[int]:
    """Queue one subtask of ``kind`` per args (site and creator of the parent), in one transaction."""
    with ctx.runtime.storage.db.session() as session:
        return [
            job_service.submit(
                session, ctx.enqueue, kind, a, site_id=ctx.job.site_id, created_by=ctx.job.created_by,
                parent_id=ctx.job.id,
            ).id
            for a in args
        ]  # fmt: skip


def await_subtasks(ctx: JobContext, ids: list[int], stage: str, task: TaskFn) -> list[dict[str, Any]]:
    """Run the parent's queued subtasks ``ids`` here with ``task``, wait for those running elsewhere.

    Progress is reported under ``stage`` as the fraction of subtasks done (running ones in part).

    Returns:
        The subtasks' results, in the order of ``ids``.

    Raises:
        DriftmapError: a subtask failed (its error is named).
        JobCancelled: a subtask was cancelled, or the parent was.
    """
    while True:
        with ctx.runtime.storage.db.session() as session:
            rows = {
                j.id: (j.status, j.error, j.result, j.progress, j.kind)
                for j in job_service.children(session, ctx.job.id)
            }
        states = [rows[i] for i in ids]
        failed = [(i, s[1], s[4]) for i, s in zip(ids, states, strict=True) if s[0] == "failed"]
        if failed:
            raise DriftmapError(f"{failed[0][2]} subtask {failed[0][0]} failed: {failed[0][1]}")
        if any(s[0] == "cancelled" for s in states):
            raise job_service.JobCancelled(f"job {ctx.job.id}: a subtask was cancelled")
        done = sum(s[0] == "succeeded" for s in states)
        if done == len(ids):
            return [dict(s[2] or {}) for s in states]
        running = sum(s[3] for s in states if s[0] == "running")
        ctx.report(stage, (done + running) / len(ids))  # also: a cancel of the parent stops it here
        queued = [(i, s[4]) for i, s in zip(ids, states, strict=True) if s[0] == "queued"]
        if queued:
            job_id, kind = queued[0]
            try:  # claims it unless another worker was quicker; its outcome is on its row
                run_job(
                    ctx.runtime, _reporting_to(ctx, stage, (done, len(ids)), task), kind, job_id, ctx.enqueue
                )
            except Exception:  # re-queued for a retry (or failed after its last attempt): seen above
                log.warning("subtask %s hit an unexpected error", job_id, exc_info=True)
        else:
            time.sleep(POLL_S)


def _reporting_to(parent: JobContext, stage: str, done_of: tuple[int, int], task: TaskFn) -> TaskFn:
    """``task`` run by the parent itself, its progress also shown as the parent's.

    A cancel of the parent stops the subtask at once (it was asked to stop too); a parent taken from
    this worker lets the subtask finish, since the parent's next run can use it.
    """
    done, n = done_of

    def run(ctx: JobContext) -> None:
        own = ctx.report

        def report(sub_stage: str, fraction: float) -> None:
            own(sub_stage, fraction)
            with contextlib.suppress(job_service.JobLost):
                parent.report(stage, (done + fraction) / n)

        ctx.report = report
        task(ctx)

    return run


def stop_subtasks(ctx: JobContext) -> None:
    """Cancel the parent's unfinished subtasks."""
    with ctx.runtime.storage.db.session() as session:
        job_service.cancel_children(session, ctx.job.id)


def drop_blobs(ctx: JobContext, shas: Sequence[str]) -> None:
    """Delete blobs the parent's subtasks handed over, unless an unfinished parent's subtask names the
    same blob (by content) in its args or result (keys ending in ``_sha256``)."""
    storage = ctx.runtime.storage
    with storage.db.session() as session:
        open_parents = select(Job.id).where(Job.status.in_(("queued", "running")), Job.id != ctx.job.id)
        others = session.execute(select(Job.args, Job.result).where(Job.parent_id.in_(open_parents)))
        keep = {
            str(v)
            for a, r in others
            for d in (a or {}, r or {})
            for k, v in d.items()
            if k.endswith("_sha256")
        }
    for sha in dict.fromkeys(shas):
        if sha not in keep:
            storage.blobs.delete(sha)

"""Jobs: list, detail, cancel, a progress stream (Server-Sent Events), and a localisation job's CSV."""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, Query, Request
from fastapi.responses import Response, StreamingResponse
from starlette.concurrency import run_in_threadpool

from driftmap.api.deps import SURVEYOR, VIEWER, SessionDep, StorageDep
from driftmap.api.input_types import Count, Id
from driftmap.api.schemas_data import JobRead, Page
from driftmap.errors import NotFoundError
from driftmap.jobs.queue import JobQueue
from driftmap.services import jobs as job_service
from driftmap.store.job_models import Job
from driftmap.store.storage import Storage

router = APIRouter(tags=["jobs"])
JobStatus = Literal["queued", "running", "succeeded", "failed", "cancelled"]
JobKind = Literal["map.build", "drive.localise", "drive.import", "site.simulate", "map.drive", "map.loops"]

STREAM_POLL_S = 0.5  # how often the progress stream looks at the job row
STREAM_KEEPALIVE_S = 15.0  # a comment line this often keeps proxies from closing a quiet stream


def _queue(request: Request) -> JobQueue:
    queue: JobQueue | None = getattr(request.app.state, "job_queue", None)
    if queue is None:
        queue = JobQueue(request.app.state.settings)
        request.app.state.job_queue = queue
    return queue


QueueDep = Annotated[JobQueue, Depends(_queue)]
"""The job queue of the app's settings (tests may put one on ``app.state.job_queue``)."""


@router.get("/jobs", dependencies=[Depends(VIEWER)])
def list_jobs(
    session: SessionDep,
    site_id: Id | None = None,
    status: JobStatus | None = None,
    kind: JobKind | None = None,
    parent_id: Annotated[
        Id | None, Query(description="List this job's subtasks instead of the top-level jobs.")
    ] = None,
    offset: Annotated[Count, Query()] = 0,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
) -> Page[JobRead]:
    """Top-level jobs (or the subtasks of ``parent_id``), newest first, optionally of one site, status or kind."""
    rows, total = job_service.list_jobs(
        session, site_id=site_id, status=status, kind=kind, parent_id=parent_id, offset=offset, limit=limit
    )
    return Page[JobRead](
        items=[JobRead.model_validate(j) for j in rows], total=total, offset=offset, limit=limit
    )


ACCEPTED: dict[int | str, dict[str, Any]] = {
    202: {
        "description": "The job was queued; follow it at ``Location``.",
        "headers": {
            "Location": {
                "description": "The job's resource, ``/api/jobs/{job_id}``.",
                "schema": {"type": "string"},
            }
        },
    }
}
"""The ``responses=`` of every route answered by :func:`accepted`."""


def accepted(request: Request, response: Response, job: Job) -> JobRead:
    """The answer to a request that submitted ``job`` (202 Accepted): its record, with ``Location`` naming
    where to follow it (``GET /api/jobs/{job_id}``)."""
    response.headers["Location"] = request.url_for("get_job", job_id=job.id).path
    return JobRead.model_validate(job)


@router.get("/jobs/{job_id}", dependencies=[Depends(VIEWER)])
def get_job(job_id: Id, session: SessionDep) -> JobRead:
    """One job: status, progress (0-1) within its stage, error or result."""
    return JobRead.model_validate(job_service.get_job(session, job_id))


@router.post("/jobs/{job_id}/cancel", dependencies=[Depends(SURVEYOR)])
def cancel_job(job_id: Id, session: SessionDep) -> JobRead:
    """Cancel a job: a queued one never starts, a running one stops at its next progress report."""
    return JobRead.model_validate(job_service.cancel(session, job_id))


def _snapshot(storage: Storage, job_id: Id) -> dict[str, object]:
    with storage.db.session() as session:
        return JobRead.model_validate(job_service.get_job(session, job_id)).model_dump(mode="json")


async def _events(request: Request, storage: Storage, job_id: Id) -> AsyncIterator[str]:
    last: dict[str, object] | None = None
    quiet_s = 0.0
    while True:
        snapshot = await run_in_threadpool(_snapshot, storage, job_id)
        if snapshot != last:
            yield f"event: job\ndata: {json.dumps(snapshot)}\n\n"
            last, quiet_s = snapshot, 0.0
        if snapshot["status"] in job_service.FINAL_STATUSES or await request.is_disconnected():
            return
        await asyncio.sleep(STREAM_POLL_S)
        quiet_s += STREAM_POLL_S
        if quiet_s >= STREAM_KEEPALIVE_S:
            yield ": keep-alive\n\n"
            quiet_s = 0.0


@router.get(
    "/jobs/{job_id}/events",
    dependencies=[Depends(VIEWER)],
    response_class=StreamingResponse,
    responses={200: {"content": {"text/event-stream": {}}}},
)
def job_events(job_id: Id, request: Request, storage: StorageDep, session: SessionDep) -> StreamingResponse:
    """Server-Sent Events: an ``event: job`` with the job as JSON at every change, until it finishes."""
    job_service.get_job(session, job_id)  # 404 before the stream starts
    return StreamingResponse(
        _events(request, storage, job_id),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
    )


@router.get(
    "/jobs/{job_id}/localisation.csv",
    dependencies=[Depends(VIEWER)],
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}},
)
def localisation_csv(job_id: Id, session: SessionDep, storage: StorageDep) -> Response:
    """The ``frame,node,x,y,score,matched`` CSV of a finished drive.localise job."""
    job = job_service.get_job(session, job_id)
    sha = (job.result or {}).get("csv_sha256")
    if job.kind != "drive.localise" or job.status != "succeeded" or not isinstance(sha, str):
        raise NotFoundError(f"job {job_id} is not a finished localisation job")
    return Response(storage.blobs.get(sha), media_type="text/csv")

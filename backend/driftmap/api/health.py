"""``GET /api/health``: open to everyone, for load balancers, start-up scripts and operators.

The answer is 200 while the database answers, with ``status`` ``ok``, or ``degraded`` and the parts at fault
in ``problems``: no job worker reported within ``health_worker_stale_s`` (jobs would wait forever), the
queue is stalled (jobs waited ``health_queue_stall_s`` while none moved), or Redis (when configured) does
not answer. It is 503 when the database does not answer (the process cannot serve anything).
"""

from __future__ import annotations

import asyncio

import redis.asyncio as aioredis
from fastapi import APIRouter, Request, Response, status
from pydantic import BaseModel
from redis.exceptions import RedisError
from sqlalchemy import text
from sqlalchemy.exc import SQLAlchemyError
from starlette.concurrency import run_in_threadpool

from driftmap import __version__
from driftmap.config import Settings
from driftmap.services import supervision
from driftmap.store.storage import Storage

router = APIRouter(tags=["health"])
REDIS_TIMEOUT_S = 2.0
"""How long the Redis ping may take before Redis counts as unreachable, seconds."""


class QueueHealth(BaseModel):
    queued: int
    """Jobs waiting to run."""
    running: int
    """Jobs a worker runs now."""
    oldest_queued_s: float | None
    """Age of the oldest waiting job, seconds."""
    stalled: bool


class Health(BaseModel):
    status: str
    """``ok``, ``degraded`` (see ``problems``) or ``down`` (the database does not answer; HTTP 503)."""
    version: str
    problems: list[str] = []
    """What is wrong, one sentence per part; empty when ``ok``."""
    database: str = "ok"
    """``ok`` or ``unreachable``."""
    redis: str = "not configured"
    """``ok``, ``unreachable`` or ``not configured``."""
    workers: int = 0
    """Job workers that reported within ``health_worker_stale_s``."""
    queue: QueueHealth | None = None


def _database_view(storage: Storage, settings: Settings) -> tuple[int, supervision.QueueState]:
    with storage.db.session() as session:
        session.execute(text("SELECT 1"))
        workers = supervision.live_workers(session, settings.health_worker_stale_s)
        return len(workers), supervision.queue_state(session, settings.health_queue_stall_s)


async def _redis_answers(url: str) -> bool:
    client = aioredis.Redis.from_url(
        url, socket_timeout=REDIS_TIMEOUT_S, socket_connect_timeout=REDIS_TIMEOUT_S
    )
    try:
        return bool(await asyncio.wait_for(client.ping(), REDIS_TIMEOUT_S))
    except (RedisError, OSError, TimeoutError):
        return False
    finally:
        await client.aclose()


@router.get("/health", responses={503: {"model": Health, "description": "The database does not answer."}})
async def health(request: Request, response: Response) -> Health:
    """Whether the server, its database, its job workers and queue, and Redis are working."""
    settings: Settings = request.app.state.settings
    answer = Health(status="ok", version=__version__)
    if settings.redis_url:
        answer.redis = "ok" if await _redis_answers(settings.redis_url) else "unreachable"
        if answer.redis != "ok":
            answer.problems.append("Redis does not answer")
    try:
        workers, queue = await run_in_threadpool(_database_view, request.app.state.storage, settings)
    except SQLAlchemyError:
        answer.status, answer.database = "down", "unreachable"
        answer.problems.insert(0, "the database does not answer")
        response.status_code = status.HTTP_503_SERVICE_UNAVAILABLE
        return answer
    answer.workers = workers
    answer.queue = QueueHealth(
        queued=queue.queued,
        running=queue.running,
        oldest_queued_s=queue.oldest_queued_s,
        stalled=queue.stalled,
    )
    if workers == 0:
        answer.problems.append(f"no job worker reported in the last {settings.health_worker_stale_s:g} s")
    if queue.stalled:
        answer.problems.append(
            f"the job queue is stalled: {queue.queued} job(s) waiting, the oldest for {queue.oldest_queued_s:.0f} s"
        )
    if answer.problems:
        answer.status = "degraded"
    return answer

"""Server and CLI settings, read from ``DRIFTMAP_*`` environment variables."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic_settings import BaseSettings, SettingsConfigDict


class Settings(BaseSettings):
    """Where driftmap keeps its data and which services it talks to."""

    model_config = SettingsConfigDict(env_prefix="DRIFTMAP_", env_file=None, extra="ignore")

    data_dir: Path = Path("./data")
    """Directory of the embedded SQLite database and of the frame blob store."""
    database_url: str | None = None
    """SQLAlchemy URL; when unset, ``sqlite:///<data_dir>/driftmap.sqlite3``."""
    redis_url: str | None = None
    """Redis URL for the job queue; when unset, an SQLite-backed queue under ``data_dir``."""
    secret_key: str | None = None
    """Key signing login tokens; when unset, a random key kept in ``<data_dir>/secret_key``."""
    token_ttl_s: float = 12 * 3600.0
    """Lifetime of a login token, seconds."""
    stale_after_s: float = 10.0
    """A vehicle with no position for this long is shown as stale (and gets a ``stale`` event), seconds."""
    event_low_confidence_s: float = 10.0
    """A vehicle whose positions stay unmatched this long (its clock) gets a ``low_confidence`` event, seconds."""
    event_check_every_s: float = 1.0
    """How often each API process looks for vehicles gone silent (``stale`` events), seconds."""
    max_upload_bytes: int = 4 * 1024**3
    """Largest accepted upload (drive zip, video, DXF), bytes."""
    max_frame_bytes: int = 8 * 1024**2
    """Largest accepted live frame image, bytes."""
    live_processes: int = 2
    """Localiser worker processes of each API process (live frames), about one per core."""

    # DXF survey plans: what reading and storing one may cost (docs/formats.md, DXF limits)
    survey_max_file_bytes: int = 64 * 1024**2
    """Largest survey DXF, bytes (also bounded by ``max_upload_bytes``)."""
    survey_max_entities: int = 500_000
    """Most entities read from one plan, block contents counted again for every reference."""
    survey_max_extent_m: float = 100_000.0
    """Largest side of a plan's bounding box, metres."""
    survey_max_curve_points: int = 100_000
    """Most points one flattened curve, polyline or hatch boundary may have."""
    survey_max_points: int = 1_000_000
    """Most points of a whole plan once its curves are flattened."""
    survey_max_stored_bytes: int = 128 * 1024**2
    """Largest JSON of a plan's parsed layers and first-view levels in the database, bytes."""

    # Logs (docs/operations.md, Logs).
    log_level: Literal["DEBUG", "INFO", "WARNING", "ERROR"] | None = None
    """Lowest level logged; None: INFO for ``driftmap serve`` and ``driftmap worker``, WARNING otherwise."""
    log_format: Literal["text", "json"] = "text"
    """``json``: one JSON object per line (time, level, logger, message, request_id, exc)."""

    # Position history retention, applied by the job workers (docs/operations.md, Position history).
    history_full_days: float = 7.0
    """Every stored position is kept this many days (by the time the server received it)."""
    history_downsample_s: float = 10.0
    """Older positions are thinned to the first of every this many seconds per vehicle; 0: not thinned."""
    history_keep_days: float = 365.0
    """Positions older than this many days are deleted; 0: kept for ever."""
    history_catch_up_days: float = 7.0
    """Each pass thins the positions that aged past ``history_full_days`` in the last this many days."""
    history_every_s: float = 3600.0
    """How often a worker applies the retention, seconds; 0: never."""

    # Login throttling and password hashing, health and supervision (docs/operations.md).
    login_max_failures_per_user: int = 10
    """Failed logins of one user name within ``login_failure_window_s`` before further tries get 429."""
    login_max_failures_per_address: int = 50
    """Failed logins from one client address within ``login_failure_window_s`` before further tries get 429."""
    login_failure_window_s: float = 900.0
    """Window over which failed logins are counted, seconds; a refused client may retry when it ends."""
    login_hash_concurrency: int = 1
    """Password hashes (argon2id, 64 MiB each) computed at once by one API process; other logins wait."""
    login_waiting_max: int = 8
    """Logins that may wait for a hashing slot; beyond that a login is answered 429 at once."""
    health_worker_stale_s: float = 30.0
    """``/api/health`` counts a job worker as alive if it reported within this many seconds."""
    health_queue_stall_s: float = 600.0
    """``/api/health`` calls the queue stalled when jobs wait this long while no job moves, seconds."""

    # Input limits: requests over them are refused (413/422 naming the field) before any work is done.
    max_frame_pixels: int = 4096 * 4096
    """Largest frame (live or drive) width x height, pixels, read from the image header before decoding."""
    max_json_bytes: int = 1024**2
    """Largest JSON request body, bytes (uploads have ``max_upload_bytes``, frames ``max_frame_bytes``)."""

    def resolved_database_url(self) -> str:
        """The database URL in force: the configured one or the embedded SQLite file."""
        if self.database_url:
            return self.database_url
        return f"sqlite:///{(self.data_dir / 'driftmap.sqlite3').resolve()}"

    @property
    def blob_dir(self) -> Path:
        """Root of the content-addressed blob store."""
        return self.data_dir / "blobs"


@lru_cache(maxsize=1)
def get_settings() -> Settings:
    """The process-wide settings, read once from the environment."""
    return Settings()

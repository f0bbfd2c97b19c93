"""SQLAlchemy 2 models of everything driftmap stores.

Frame pixels and original files live in the blob store; rows hold their SHA-256 and small metadata.
Positions are survey-frame metres (x east, y north), headings radians counter-clockwise from +x,
times seconds since drive start. The schema changes only through Alembic migrations.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from sqlalchemy import (
    JSON,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    MetaData,
    String,
    Text,
    UniqueConstraint,
    true,
)
from sqlalchemy.engine import Dialect
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship
from sqlalchemy.types import TypeDecorator

from driftmap.formats.records import STATION_MAX_CHARS

NAMING_CONVENTION = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


def utc_now() -> datetime:
    """The current time, timezone-aware UTC."""
    return datetime.now(UTC)


class UtcDateTime(TypeDecorator[datetime]):
    """A moment in time, stored in UTC and always read back timezone-aware (UTC).

    PostgreSQL keeps the zone itself; SQLite stores the UTC wall time and returns it naive, which is tagged
    UTC here, so every API answer states its zone on either database. Naive values are refused on write.
    """

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("a stored moment must be timezone-aware")
        return value.astimezone(UTC)

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None or value.tzinfo is UTC:
            return value
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING_CONVENTION)
    type_annotation_map = {dict[str, Any]: JSON}  # noqa: RUF012 (SQLAlchemy reads it as a class attribute)


class Site(Base):
    """One mine (or one part of a mine) with its own survey grid."""

    __tablename__ = "sites"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)
    description: Mapped[str] = mapped_column(Text, default="")
    crs: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True, default=None)
    """The plane's mine-grid transform and EPSG code (:class:`driftmap.formats.site_crs.SiteCrs` as JSON)."""
    created_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)

    survey_maps: Mapped[list[SurveyMap]] = relationship(
        back_populates="site", cascade="all, delete-orphan", order_by="SurveyMap.id"
    )
    drives: Mapped[list[Drive]] = relationship(
        back_populates="site", cascade="all, delete-orphan", order_by="Drive.id"
    )


class SurveyMap(Base):
    """A surveyed DXF plan of a site: the original file (a blob) and its parsed layers."""

    __tablename__ = "survey_maps"

    id: Mapped[int] = mapped_column(primary_key=True)
    site_id: Mapped[int] = mapped_column(ForeignKey("sites.id", ondelete="CASCADE"), index=True)
    filename: Mapped[str] = mapped_column(String(500))
    dxf_sha256: Mapped[str] = mapped_column(String(64))
    units: Mapped[str] = mapped_column(String(20), default="m")
    min_x_m: Mapped[float] = mapped_column(Float)
    min_y_m: Mapped[float] = mapped_column(Float)
    max_x_m: Mapped[float] = mapped_column(Float)
    max_y_m: Mapped[float] = mapped_column(Float)
    layers: Mapped[dict[str, Any]] = mapped_column(JSON, deferred=True)
    """Layer name -> GeoJSON-like FeatureCollection in plane metres (loaded on first access: it can be large)."""
    created_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)

    site: Mapped[Site] = relationship(back_populates="survey_maps")


class SurveyLayerLevel(Base):
    """A survey map's layers simplified to one tolerance, stored at upload for the zooms a first view asks.

    Written in the upload's transaction (see services/survey_layers.py), so a plan never exists without its
    levels and a failed upload leaves neither. Deleted with its survey map (database cascade).
    """

    __tablename__ = "survey_layer_levels"
    __table_args__ = (
        UniqueConstraint(
            "survey_map_id", "tolerance_m", name="uq_survey_layer_levels_survey_map_id_tolerance_m"
        ),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    survey_map_id: Mapped[int] = mapped_column(ForeignKey("survey_maps.id", ondelete="CASCADE"), index=True)
    zoom: Mapped[int] = mapped_column(Integer)
    """The map zoom the level was computed for (0: the plan spans 256 px)."""
    tolerance_m: Mapped[float] = mapped_column(Float)
    """Simplification tolerance, metres, rounded as the lookup key (``services.survey_layers.tolerance_key``)."""
    vertices: Mapped[dict[str, Any]] = mapped_column(JSON)
    """Layer name -> vertices left after simplification."""
    layers: Mapped[dict[str, Any] | None] = mapped_column(JSON(none_as_null=True), deferred=True)
    """Layer name -> simplified GeoJSON FeatureCollection in plane metres (None: see ``same_as_zoom``)."""
    same_as_zoom: Mapped[int | None] = mapped_column(Integer)
    """When set, this level's layers are those of the same plan's level at that coarser zoom (stored once)."""


class Drive(Base):
    """One recorded drive of one vehicle: its camera calibration and its frames."""

    __tablename__ = "drives"
    __table_args__ = (UniqueConstraint("site_id", "name", name="uq_drives_site_id_name"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    site_id: Mapped[int] = mapped_column(ForeignKey("sites.id", ondelete="CASCADE"), index=True)
    name: Mapped[str] = mapped_column(String(200))
    kind: Mapped[str] = mapped_column(String(20))
    fps: Mapped[float] = mapped_column(Float)
    camera: Mapped[dict[str, Any]] = mapped_column(JSON)
    """The ``camera`` block of drive.json, verbatim keys of formats.md."""
    frame_count: Mapped[int] = mapped_column(Integer, default=0)
    source: Mapped[str] = mapped_column(String(1000), default="")
    created_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)

    site: Mapped[Site] = relationship(back_populates="drives")
    frames: Mapped[list[Frame]] = relationship(
        back_populates="drive", cascade="all, delete-orphan", order_by="Frame.index", passive_deletes=True
    )
    groundings: Mapped[list[Grounding]] = relationship(
        back_populates="drive", cascade="all, delete-orphan", order_by="Grounding.id", passive_deletes=True
    )


class Frame(Base):
    """One camera frame of a drive; pixels in the blob store under ``blob_sha256``."""

    __tablename__ = "frames"
    __table_args__ = (UniqueConstraint("drive_id", "index", name="uq_frames_drive_id_index"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    drive_id: Mapped[int] = mapped_column(ForeignKey("drives.id", ondelete="CASCADE"), index=True)
    index: Mapped[int] = mapped_column(Integer)
    """The frame number of the drive folder's file name."""
    t_s: Mapped[float] = mapped_column(Float)
    blob_sha256: Mapped[str] = mapped_column(String(64), index=True)
    image_ext: Mapped[str] = mapped_column(String(8))
    true_x_m: Mapped[float | None] = mapped_column(Float, nullable=True)
    true_y_m: Mapped[float | None] = mapped_column(Float, nullable=True)
    true_yaw_rad: Mapped[float | None] = mapped_column(Float, nullable=True)

    drive: Mapped[Drive] = relationship(back_populates="frames")


class Grounding(Base):
    """A surveyor's statement: this frame was taken at this surveyed point.

    ``station`` names the survey station (e.g. ``STN-104``) when the point is one; a grounding that is not
    ``enabled`` is kept but map builds leave it out.
    """

    __tablename__ = "groundings"
    __table_args__ = (UniqueConstraint("frame_id", name="uq_groundings_frame_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    drive_id: Mapped[int] = mapped_column(ForeignKey("drives.id", ondelete="CASCADE"), index=True)
    frame_id: Mapped[int] = mapped_column(ForeignKey("frames.id", ondelete="CASCADE"))
    x_m: Mapped[float] = mapped_column(Float)
    y_m: Mapped[float] = mapped_column(Float)
    station: Mapped[str | None] = mapped_column(String(STATION_MAX_CHARS), nullable=True)
    enabled: Mapped[bool] = mapped_column(default=True, server_default=true())
    created_by: Mapped[str] = mapped_column(String(200), default="import")
    created_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)
    updated_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now, onupdate=utc_now)

    drive: Mapped[Drive] = relationship(back_populates="groundings")
    frame: Mapped[Frame] = relationship()


class MapVersion(Base):
    """One immutable build of a site's map: optimised poses, closures, residuals, topological map.

    ``version`` counts up per site from 1. The topological map's arrays (node positions, sparse
    adjacency) are one ``.npz`` blob named by ``topomap_sha256``; nodes and node frames are also rows
    so that the API can query them.
    """

    __tablename__ = "map_versions"
    __table_args__ = (UniqueConstraint("site_id", "version", name="uq_map_versions_site_id_version"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    site_id: Mapped[int] = mapped_column(ForeignKey("sites.id", ondelete="CASCADE"), index=True)
    version: Mapped[int] = mapped_column(Integer)
    params: Mapped[dict[str, Any]] = mapped_column(JSON)
    stats: Mapped[dict[str, Any]] = mapped_column(JSON)
    """Build figures: frames, keyframes, closures, graph errors, seconds per stage."""
    topomap_sha256: Mapped[str] = mapped_column(String(64))
    created_by: Mapped[str] = mapped_column(String(200), default="cli")
    created_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)


class MapPiece(Base):
    """A map build's stage-1 piece of one drive segment, kept for the next build of the site.

    The piece (odometry steps, thumbnails, frame statistics: an ``.npz`` blob named by ``blob_sha256``)
    depends only on what ``piece_key`` hashes: the drive's frames and camera, the segment's frames
    ``[frame_first, frame_stop)``, the parameters stage 1 uses and the code's piece version
    (:mod:`driftmap.services.map_pieces`). A build whose key matches reuses the blob instead of re-running
    the odometry; a build replaces its drives' pieces of other keys.
    """

    __tablename__ = "map_pieces"
    __table_args__ = (UniqueConstraint("piece_key", name="uq_map_pieces_piece_key"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    drive_id: Mapped[int] = mapped_column(ForeignKey("drives.id", ondelete="CASCADE"), index=True)
    piece_key: Mapped[str] = mapped_column(String(64))
    frame_first: Mapped[int] = mapped_column(Integer)
    frame_stop: Mapped[int] = mapped_column(Integer)
    blob_sha256: Mapped[str] = mapped_column(String(64), index=True)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)


class MapLoopSearch(Base):
    """A site's latest loop-closure search, kept for the site's next map build to resume.

    ``chains`` lists the key of each chain the search covered (a drive's keyframes), in search order;
    ``search_key`` hashes its parameters and the code's search version; ``basis_sha256`` names the search's
    basis (``.npz``: descriptor mean, axes and descriptors, thresholds) and ``blocks`` its query blocks'
    scores as ``[q0, q1, blob SHA-256]`` rows (:mod:`driftmap.services.loop_searches`). A build whose first
    chains are those of the kept search scores only the queries after them.
    """

    __tablename__ = "map_loop_searches"
    __table_args__ = (UniqueConstraint("site_id", name="uq_map_loop_searches_site_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    site_id: Mapped[int] = mapped_column(ForeignKey("sites.id", ondelete="CASCADE"))
    search_key: Mapped[str] = mapped_column(String(64))
    chains: Mapped[list[str]] = mapped_column(JSON)
    basis_sha256: Mapped[str] = mapped_column(String(64))
    blocks: Mapped[list[list[Any]]] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)


class MapDatabaseScores(Base):
    """A site's latest SESAME database pair scores, kept for the site's next map build.

    ``drives`` lists the key of each drive the scores cover (its chain key,
    :func:`driftmap.services.loop_searches.chain_keys`); ``scores_key`` hashes the parameters they depend
    on and the code's version; ``scores_sha256`` names an ``.npz`` of the scored pairs (positions in
    ``drives`` and frame rows of query and reference, and the score;
    :mod:`driftmap.services.database_scores`).
    """

    __tablename__ = "map_database_scores"
    __table_args__ = (UniqueConstraint("site_id", name="uq_map_database_scores_site_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    site_id: Mapped[int] = mapped_column(ForeignKey("sites.id", ondelete="CASCADE"))
    scores_key: Mapped[str] = mapped_column(String(64))
    drives: Mapped[list[str]] = mapped_column(JSON)
    scores_sha256: Mapped[str] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)


class MapPose(Base):
    """The optimised pose of one mapping frame in one map version (survey frame, metres, radians)."""

    __tablename__ = "map_poses"
    __table_args__ = (
        UniqueConstraint("map_version_id", "frame_id", name="uq_map_poses_map_version_id_frame_id"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    map_version_id: Mapped[int] = mapped_column(ForeignKey("map_versions.id", ondelete="CASCADE"), index=True)
    frame_id: Mapped[int] = mapped_column(ForeignKey("frames.id", ondelete="CASCADE"))
    x_m: Mapped[float] = mapped_column(Float)
    y_m: Mapped[float] = mapped_column(Float)
    yaw_rad: Mapped[float] = mapped_column(Float)


class MapLoopClosure(Base):
    """A loop closure found during a build, with its SAD score and whether the optimiser kept it."""

    __tablename__ = "map_loop_closures"

    id: Mapped[int] = mapped_column(primary_key=True)
    map_version_id: Mapped[int] = mapped_column(ForeignKey("map_versions.id", ondelete="CASCADE"), index=True)
    frame_a_id: Mapped[int] = mapped_column(ForeignKey("frames.id", ondelete="CASCADE"))
    frame_b_id: Mapped[int] = mapped_column(ForeignKey("frames.id", ondelete="CASCADE"))
    d_score: Mapped[float] = mapped_column(Float)
    accepted: Mapped[bool] = mapped_column()
    chi2: Mapped[float] = mapped_column(Float)


class MapGroundingResidual(Base):
    """How far the optimised map lands from one grounding: optimised minus surveyed, metres."""

    __tablename__ = "map_grounding_residuals"

    id: Mapped[int] = mapped_column(primary_key=True)
    map_version_id: Mapped[int] = mapped_column(ForeignKey("map_versions.id", ondelete="CASCADE"), index=True)
    grounding_id: Mapped[int | None] = mapped_column(
        ForeignKey("groundings.id", ondelete="SET NULL"), nullable=True
    )
    frame_id: Mapped[int] = mapped_column(ForeignKey("frames.id", ondelete="CASCADE"))
    surveyed_x_m: Mapped[float] = mapped_column(Float)
    surveyed_y_m: Mapped[float] = mapped_column(Float)
    dx_m: Mapped[float] = mapped_column(Float)
    dy_m: Mapped[float] = mapped_column(Float)
    distance_m: Mapped[float] = mapped_column(Float)


class MapNode(Base):
    """A place of the compressed topological map (paper III-A-4), every N metres."""

    __tablename__ = "map_nodes"
    __table_args__ = (UniqueConstraint("map_version_id", "node", name="uq_map_nodes_map_version_id_node"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    map_version_id: Mapped[int] = mapped_column(ForeignKey("map_versions.id", ondelete="CASCADE"), index=True)
    node: Mapped[int] = mapped_column(Integer)
    x_m: Mapped[float] = mapped_column(Float)
    y_m: Mapped[float] = mapped_column(Float)


class MapNodeFrame(Base):
    """A frame chosen to represent a node (several per node: headings, appearances)."""

    __tablename__ = "map_node_frames"

    id: Mapped[int] = mapped_column(primary_key=True)
    map_version_id: Mapped[int] = mapped_column(ForeignKey("map_versions.id", ondelete="CASCADE"), index=True)
    node: Mapped[int] = mapped_column(Integer)
    frame_id: Mapped[int] = mapped_column(ForeignKey("frames.id", ondelete="CASCADE"))
    rank: Mapped[int] = mapped_column(Integer)


class CameraProfile(Base):
    """A named, stored ``camera`` block (drive.json keys of formats.md) that vehicles can be given.

    Profiles are global (one camera model and mount is often fitted to many vehicles on several sites); the
    block is validated as a drive import validates it and stored in its canonical form.
    """

    __tablename__ = "camera_profiles"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)
    description: Mapped[str] = mapped_column(Text, default="")
    camera: Mapped[dict[str, Any]] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)
    updated_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now, onupdate=utc_now)

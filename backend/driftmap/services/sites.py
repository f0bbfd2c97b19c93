"""Sites and their survey maps."""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.config import Settings
from driftmap.errors import BadInputError, ConflictError, NotFoundError, PayloadTooLargeError
from driftmap.formats.site_crs import SiteCrs
from driftmap.formats.survey_dxf import DEFAULT_LIMITS, DxfLimits, read_survey_dxf, survey_map_to_json
from driftmap.services import survey_layers
from driftmap.store.blobs import BlobBatch
from driftmap.store.models import Site, SurveyMap


def get_site(session: Session, name_or_id: str | int) -> Site:
    """The site named ``name_or_id`` (or with that numeric id)."""
    site = session.scalar(select(Site).where(Site.name == str(name_or_id)))
    if site is None and str(name_or_id).isdigit():
        site = session.get(Site, int(name_or_id))
    if site is None:
        raise NotFoundError(f"no site named {name_or_id!r}")
    return site


def list_sites(session: Session) -> list[Site]:
    """Every site, oldest first."""
    return list(session.scalars(select(Site).order_by(Site.id)))


def create_site(session: Session, name: str, description: str = "") -> Site:
    """A new, empty site; the name must be unused."""
    name = name.strip()
    if not name:
        raise BadInputError("a site needs a non-empty name", field="name")
    if session.scalar(select(Site.id).where(Site.name == name)) is not None:
        raise ConflictError(f"a site named {name!r} already exists")
    site = Site(name=name, description=description)
    session.add(site)
    session.flush()
    return site


def site_crs(site: Site) -> SiteCrs:
    """The site's mine-grid transform and EPSG code (plane metres, no CRS, when none was set)."""
    return SiteCrs() if site.crs is None else SiteCrs.from_json(site.crs)


def set_site_crs(session: Session, site: Site, crs: SiteCrs | None) -> Site:
    """Place the site's plane on the mine grid (and with an EPSG code on the Earth); None clears it.
    Exports written from then on use it; nothing stored in plane metres changes."""
    site.crs = None if crs is None or crs.is_plane else crs.to_json()
    session.flush()
    return site


def survey_limits(settings: Settings) -> DxfLimits:
    """The ``survey_max_*`` settings as the DXF reader's limits."""
    return DxfLimits(
        max_file_bytes=settings.survey_max_file_bytes,
        max_entities=settings.survey_max_entities,
        max_extent_m=settings.survey_max_extent_m,
        max_curve_points=settings.survey_max_curve_points,
        max_points=settings.survey_max_points,
        max_stored_bytes=settings.survey_max_stored_bytes,
    )


def add_survey_map(
    session: Session,
    batch: BlobBatch,
    site: Site,
    data: bytes,
    filename: str,
    limits: DxfLimits = DEFAULT_LIMITS,
) -> SurveyMap:
    """Parse a DXF plan and store it (original bytes as a blob, parsed layers as JSON) on ``site``.

    The layers simplified for a first view's zooms are added in the same session (see
    :func:`survey_layers.store_first_levels`): they commit or roll back with the plan. Every limit is
    checked before anything is added, so a refused plan leaves the site as it was.

    Raises:
        BadInputError: a plan :func:`read_survey_dxf` refuses.
        PayloadTooLargeError: a plan over ``limits``, e.g. whose parsed layers and first-view levels
            would take more than ``limits.max_stored_bytes`` of JSON in the database.
    """
    survey = read_survey_dxf(data, filename, limits)
    parsed = survey_map_to_json(survey)
    min_x, min_y, max_x, max_y = survey.extents
    record = SurveyMap(
        site_id=site.id,
        filename=Path(filename).name,
        units="m",
        min_x_m=min_x,
        min_y_m=min_y,
        max_x_m=max_x,
        max_y_m=max_y,
        layers=parsed,
    )
    levels = survey_layers.first_levels(record)
    size = survey_layers.json_bytes(parsed) + survey_layers.stored_bytes(levels)
    if size > limits.max_stored_bytes:
        raise PayloadTooLargeError(
            f"the parsed plan and its first-view levels take {size} bytes, over the "
            f"{limits.max_stored_bytes} byte limit (setting survey_max_stored_bytes)",
            file=filename,
        )
    record.dxf_sha256 = batch.put(data)
    session.add(record)
    session.flush()
    survey_layers.store_first_levels(session, record, levels)
    return record


def latest_survey_map(session: Session, site: Site) -> SurveyMap:
    """The newest survey map of ``site``."""
    record = session.scalar(
        select(SurveyMap).where(SurveyMap.site_id == site.id).order_by(SurveyMap.id.desc()).limit(1)
    )
    if record is None:
        raise NotFoundError(f"site {site.name!r} has no survey map")
    return record

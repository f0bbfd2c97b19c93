"""A site's coordinates on the mine's grid and on the Earth: a local mine-grid transform and an EPSG code.

Everything driftmap stores is in the **site plane**: x east, y north, metres, as the surveyed DXF plan draws
it. A site may say how that plane sits on the mine's grid and in a projected coordinate reference system:

* **mine grid** (a Helmert transform of the plane, as survey packages apply a local grid):
  ``E = false_easting_m + scale * (x cos r - y sin r)``, ``N = false_northing_m + scale * (x sin r + y cos r)``,
  ``r = rotation_deg`` counter-clockwise (the plane's +x turned by r is the grid's east); the identity when
  nothing is set, as for a plan drawn in grid coordinates already;
* **EPSG code** of the projected CRS the grid coordinates are in (e.g. 32733, UTM zone 33 south; metres,
  east then north): with one, exports that must be WGS84 (GeoJSON, RFC 7946; KML) carry longitude and
  latitude in degrees, computed with pyproj.

Without an EPSG code GeoJSON and KML carry grid coordinates (the plane's, when the grid transform is the
identity), and say which in the file.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError

from driftmap.core.types import F64
from driftmap.errors import BadInputError
from driftmap.formats.trajectory_exports import PLANE_COORDINATES

__all__ = ["SiteCrs"]

_FIELDS = ("epsg", "false_easting_m", "false_northing_m", "rotation_deg", "scale")


@lru_cache(maxsize=16)
def _to_wgs84(epsg: int) -> Transformer:
    return Transformer.from_crs(CRS.from_epsg(epsg), CRS.from_epsg(4326), always_xy=True)


@lru_cache(maxsize=16)
def _from_wgs84(epsg: int) -> Transformer:
    return Transformer.from_crs(CRS.from_epsg(4326), CRS.from_epsg(epsg), always_xy=True)


@dataclass(frozen=True)
class SiteCrs:
    """How a site's plane sits on the mine grid and, with ``epsg``, on the Earth (see the module doc)."""

    epsg: int | None = None
    false_easting_m: float = 0.0
    false_northing_m: float = 0.0
    rotation_deg: float = 0.0
    scale: float = 1.0

    def __post_init__(self) -> None:
        for name in _FIELDS[1:]:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise BadInputError(f"crs.{name} must be a finite number, got {value!r}", field=f"crs.{name}")
        if not 0.5 <= self.scale <= 2.0:
            raise BadInputError(f"crs.scale must be between 0.5 and 2, got {self.scale}", field="crs.scale")
        if self.epsg is not None:
            _check_epsg(self.epsg)

    @classmethod
    def from_json(cls, value: object) -> SiteCrs:
        """From a stored or posted object with any of the fields; unknown keys are refused by name."""
        if not isinstance(value, dict):
            raise BadInputError("crs must be a JSON object", field="crs")
        unknown = sorted(set(value) - set(_FIELDS))
        if unknown:
            raise BadInputError(f"crs has no field {unknown[0]!r}", field=f"crs.{unknown[0]}")
        return cls(**value)

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    @property
    def is_plane(self) -> bool:
        """Whether grid coordinates are the plane's own (no transform) and no CRS is set."""
        return self.epsg is None and self.to_json() == SiteCrs().to_json()

    def to_grid(self, xy_m: F64) -> F64:
        """(N, 2) site plane metres -> (N, 2) mine grid easting, northing, metres."""
        xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
        r = math.radians(self.rotation_deg)
        c, s = math.cos(r), math.sin(r)
        e = self.false_easting_m + self.scale * (c * xy[:, 0] - s * xy[:, 1])
        n = self.false_northing_m + self.scale * (s * xy[:, 0] + c * xy[:, 1])
        return np.column_stack([e, n])

    def from_grid(self, en_m: F64) -> F64:
        """Inverse of :meth:`to_grid`."""
        en = np.asarray(en_m, dtype=np.float64).reshape(-1, 2)
        r = math.radians(self.rotation_deg)
        c, s = math.cos(r), math.sin(r)
        de, dn = (
            (en[:, 0] - self.false_easting_m) / self.scale,
            (en[:, 1] - self.false_northing_m) / self.scale,
        )
        return np.column_stack([c * de + s * dn, -s * de + c * dn])

    def to_wgs84(self, xy_m: F64) -> F64:
        """(N, 2) site plane metres -> (N, 2) longitude, latitude, degrees (WGS84); needs ``epsg``."""
        if self.epsg is None:
            raise BadInputError(
                "the site has no EPSG code: its plane is not placed on the Earth", field="crs.epsg"
            )
        en = self.to_grid(xy_m)
        lon, lat = _to_wgs84(self.epsg).transform(en[:, 0], en[:, 1])
        return np.column_stack([lon, lat])

    def from_wgs84(self, lonlat_deg: F64) -> F64:
        """Inverse of :meth:`to_wgs84`."""
        if self.epsg is None:
            raise BadInputError(
                "the site has no EPSG code: its plane is not placed on the Earth", field="crs.epsg"
            )
        ll = np.asarray(lonlat_deg, dtype=np.float64).reshape(-1, 2)
        e, n = _from_wgs84(self.epsg).transform(ll[:, 0], ll[:, 1])
        return self.from_grid(np.column_stack([e, n]))

    def proj4(self) -> str | None:
        """The EPSG system as a PROJ string for a browser's proj4js to show longitude and latitude with, None
        without ``epsg``. A PROJ string may drop a datum shift (metres on some systems): exports use pyproj."""
        if self.epsg is None:
            return None
        with warnings.catch_warnings():  # pyproj warns that a PROJ string loses information: said above
            warnings.simplefilter("ignore", UserWarning)
            return str(CRS.from_epsg(self.epsg).to_proj4())

    def export_label(self) -> str:
        """What the coordinates of this site's GeoJSON and KML exports are, in words."""
        if self.epsg is not None:
            return f"WGS84 longitude, latitude degrees (site plane -> mine grid -> EPSG:{self.epsg})"
        if self.is_plane:
            return PLANE_COORDINATES
        return "mine grid easting, northing metres (no CRS)"

    def export_xy(self, xy_m: F64) -> F64:
        """(N, 2) plane metres as this site's GeoJSON and KML exports write them (see :meth:`export_label`)."""
        if self.epsg is not None:
            return self.to_wgs84(xy_m)
        return self.to_grid(xy_m)


def _check_epsg(epsg: object) -> None:
    if isinstance(epsg, bool) or not isinstance(epsg, int) or not 1024 <= epsg <= 999_999:
        raise BadInputError(f"crs.epsg must be an EPSG code (an integer), got {epsg!r}", field="crs.epsg")
    try:
        crs = CRS.from_epsg(epsg)
    except CRSError as exc:
        raise BadInputError(
            f"crs.epsg: EPSG:{epsg} is not a known coordinate system", field="crs.epsg"
        ) from exc
    units = {axis.unit_name for axis in crs.axis_info}
    if not crs.is_projected or units != {"metre"}:
        raise BadInputError(
            f"crs.epsg: EPSG:{epsg} ({crs.name}) is not a projected system in metres; the mine grid needs one",
            field="crs.epsg",
        )

// A site's coordinates (docs/formats.md, "Site coordinates"): the site plane (x east, y north, metres) placed on
// the mine grid by a Helmert transform, and with an EPSG code on the Earth. Longitude and latitude come from the
// EPSG system's PROJ string (the server sends it) through proj4js, WGS84 degrees.
import proj4 from "proj4";

/** The fields of a site's ``crs`` as the API reads and writes them. */
export interface SiteCrs {
  epsg?: number | null;
  false_easting_m: number;
  false_northing_m: number;
  /** Counter-clockwise angle from the plane's +x to the grid's east, degrees. */
  rotation_deg: number;
  scale: number;
  /** The ``epsg`` system as a PROJ string; null without one. */
  proj4?: string | null;
}

/** What the readout can show of a plane point besides its plane metres. */
export interface SiteCoordinates {
  /** Plane metres -> mine grid easting, northing (metres). */
  toGrid(x: number, y: number): [number, number];
  /** Whether the grid transform is the identity (the grid readout would repeat the plane's). */
  identity: boolean;
  /** Plane metres -> WGS84 longitude, latitude (degrees); null without an EPSG code. */
  toLonLat: ((x: number, y: number) => [number, number]) | null;
  epsg: number | null;
}

const WGS84 = "+proj=longlat +datum=WGS84 +no_defs";

/**
 * The site's conversions, or null when it has no coordinates. A PROJ string proj4js cannot read leaves
 * longitude and latitude out (the grid still shows).
 */
export function siteCoordinatesOf(crs: SiteCrs | null | undefined): SiteCoordinates | null {
  if (!crs) return null;
  const r = (crs.rotation_deg * Math.PI) / 180;
  const c = Math.cos(r);
  const s = Math.sin(r);
  const k = crs.scale;
  const e0 = crs.false_easting_m;
  const n0 = crs.false_northing_m;
  const toGrid = (x: number, y: number): [number, number] => [e0 + k * (c * x - s * y), n0 + k * (s * x + c * y)];
  const identity = e0 === 0 && n0 === 0 && crs.rotation_deg === 0 && k === 1;
  let toLonLat: SiteCoordinates["toLonLat"] = null;
  if (crs.proj4) {
    try {
      const converter = proj4(crs.proj4, WGS84);
      toLonLat = (x, y) => {
        const [lon, lat] = converter.forward(toGrid(x, y));
        return [lon, lat];
      };
    } catch {
      toLonLat = null;
    }
  }
  return { toGrid, identity, toLonLat, epsg: crs.epsg ?? null };
}

/** "145.038051° E  35.019819° S": longitude then latitude, 6 decimals (about 0.1 m). */
export function formatLonLat(lon: number, lat: number): string {
  const ew = lon < 0 ? "W" : "E";
  const ns = lat < 0 ? "S" : "N";
  return `${Math.abs(lon).toFixed(6)}° ${ew}  ${Math.abs(lat).toFixed(6)}° ${ns}`;
}

/** What a readout shows of a plane point: the mine grid (unless the identity) and longitude/latitude. */
export interface SiteReadout {
  grid?: string;
  lonLat?: string;
  /** Longitude, latitude, degrees (for tests and tooltips). */
  lonLatDeg?: [number, number];
}

/** The readout's lines for a plane point (none without coordinates). */
export function siteReadout(coords: SiteCoordinates | null, x: number, y: number): SiteReadout {
  if (!coords) return {};
  const out: SiteReadout = {};
  if (!coords.identity) {
    const [e, n] = coords.toGrid(x, y);
    out.grid = `grid E ${e.toFixed(2)}  N ${n.toFixed(2)}`;
  }
  if (coords.toLonLat) {
    const [lon, lat] = coords.toLonLat(x, y);
    if (Number.isFinite(lon) && Number.isFinite(lat)) {
      out.lonLat = formatLonLat(lon, lat);
      out.lonLatDeg = [lon, lat];
    }
  }
  return out;
}

// ---- the settings form ----------------------------------------------------------------------------------------

export const CRS_FIELDS = ["epsg", "false_easting_m", "false_northing_m", "rotation_deg", "scale"] as const;
export type CrsField = (typeof CRS_FIELDS)[number];
/** The form's text of each field. */
export type CrsForm = Record<CrsField, string>;
export type CrsBody = Omit<SiteCrs, "proj4">;

const DEFAULTS: CrsBody = { epsg: null, false_easting_m: 0, false_northing_m: 0, rotation_deg: 0, scale: 1 };

/** The form's text for a site's coordinates (the defaults' without any; an empty EPSG code for none). */
export function crsFormOf(crs: SiteCrs | null | undefined): CrsForm {
  const c = crs ?? DEFAULTS;
  return {
    epsg: c.epsg === null || c.epsg === undefined ? "" : String(c.epsg),
    false_easting_m: String(c.false_easting_m),
    false_northing_m: String(c.false_northing_m),
    rotation_deg: String(c.rotation_deg),
    scale: String(c.scale),
  };
}

/**
 * The PUT body of the form, or the fields that are not numbers (the server checks the ranges). An empty EPSG code
 * is none; an empty number is its default (0, or 1 for the scale).
 */
export function crsBodyOf(form: CrsForm): { body: CrsBody } | { errors: Partial<Record<CrsField, string>> } {
  const errors: Partial<Record<CrsField, string>> = {};
  const body: CrsBody = { ...DEFAULTS };
  const epsg = form.epsg.trim();
  if (epsg !== "") {
    if (/^\d+$/.test(epsg)) body.epsg = Number(epsg);
    else errors.epsg = "an EPSG code is a whole number, e.g. 28355";
  }
  for (const field of CRS_FIELDS.slice(1) as Exclude<CrsField, "epsg">[]) {
    const text = form[field].trim();
    if (text === "") continue;
    const value = Number(text);
    if (Number.isFinite(value)) body[field] = value;
    else errors[field] = "not a number";
  }
  return Object.keys(errors).length > 0 ? { errors } : { body };
}

/** The body that clears a site's coordinates. */
export const CLEAR_CRS: CrsBody = DEFAULTS;

/**
 * The field a refusal names ("crs.epsg: EPSG:4326 ... is not projected", "scale: Input should be ..."), or null
 * (then the message goes under the whole form).
 */
export function refusedField(message: string): CrsField | null {
  let best: { field: CrsField; at: number } | null = null;
  for (const field of CRS_FIELDS) {
    const at = message.search(new RegExp(`(^|[^\\w])(crs\\.)?${field}\\b`));
    if (at >= 0 && (best === null || at < best.at)) best = { field, at };
  }
  return best?.field ?? null;
}

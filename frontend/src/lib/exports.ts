// The export controls' logic: the formats of the map and position exports (as the API takes them), the time
// range the monitoring view shows (the position export's default), the position export's query from the range
// inputs, and the file name a download is saved under.
import type { operations } from "../api/schema";
import { parseClock, rangeText } from "./replay";

type QueryOf<Op extends keyof operations> = operations[Op]["parameters"]["query"];
export type MapFormat = QueryOf<"export_map_api_sites__site_id__maps__version__export_get">["format"];
export type PositionFormat = QueryOf<"export_positions_api_sites__site_id__positions_export_get">["format"];

/** The map export's formats with their labels, in the select's order. */
export const MAP_FORMATS: Record<MapFormat, string> = {
  geojson: "GeoJSON",
  csv: "CSV",
  kml: "KML",
  dxf: "DXF",
  tum: "TUM (one drive)",
  kitti: "KITTI (one drive)",
  g2o: "g2o pose graph",
};

/** The position export's formats with their labels, in the select's order. */
export const POSITION_FORMATS: Record<PositionFormat, string> = {
  csv: "CSV",
  geojson: "GeoJSON",
  kml: "KML",
  dxf: "DXF",
  tum: "TUM (one vehicle)",
  kitti: "KITTI (one vehicle)",
};

/** What the monitoring view shows of a vehicle's history, to default an export's range to. */
export interface Shown {
  /** The latest position's frame time ``t`` (vehicle clock, seconds); null without a position. */
  latestT: number | null;
  /** The loaded replay's range of this vehicle, [start, end] seconds; null without one. */
  replay: [number, number] | null;
}

/**
 * The range (inputs' text, :func:`rangeText`) the view shows: a loaded replay's range, else the ``windowS``
 * before the latest position; two empty strings (the whole history) without a position.
 */
export function shownRange(shown: Shown, windowS: number): [string, string] {
  if (shown.replay) return rangeText(...shown.replay);
  if (shown.latestT === null) return ["", ""];
  return rangeText(shown.latestT - windowS, shown.latestT);
}

/** The position export's ``since``/``until`` (seconds) from the range inputs, or why they cannot be read. */
export type RangeQuery = { since: number | null; until: number | null } | { error: string };

/**
 * Read the range inputs as :func:`parseClock` does (a bare time of day on ``reference``'s day); an empty input
 * leaves that end open.
 */
export function rangeQuery(from: string, to: string, reference: number): RangeQuery {
  const read = (text: string) => (text.trim() === "" ? null : parseClock(text, reference));
  const since = read(from);
  const until = read(to);
  if ((since === null && from.trim() !== "") || (until === null && to.trim() !== "")) {
    return { error: "Write times as YYYY-MM-DD HH:MM:SS, HH:MM:SS, +H:MM:SS (drive time) or seconds." };
  }
  if (since !== null && until !== null && until < since) return { error: "The end is before the start." };
  return { since, until };
}

/**
 * The file name of a ``Content-Disposition`` header: ``filename*`` (RFC 5987, UTF-8) before ``filename``;
 * null without one. Any folder part is dropped.
 */
export function dispositionFilename(header: string | null): string | null {
  if (!header) return null;
  let name: string | null = null;
  const extended = /filename\*\s*=\s*([^']*)'[^']*'([^;]+)/i.exec(header);
  if (extended) {
    try {
      name = decodeURIComponent(extended[2]!.trim());
    } catch {
      name = null;
    }
  }
  if (name === null) {
    const plain = /filename\s*=\s*(?:"((?:[^"\\]|\\.)*)"|([^;]+))/i.exec(header);
    if (plain) name = (plain[1] ?? plain[2] ?? "").replace(/\\(.)/g, "$1").trim();
  }
  const base = name?.split(/[/\\]/).pop() ?? "";
  return base === "" ? null : base;
}

// Snapping a clicked point to the survey plan: the nearest DXF vertex, POINT or text label's anchor when one is
// near (a label names the survey station it marks), else the nearest point on a centreline, else the click
// itself. All coordinates in mine-grid metres.

export interface SnapTargets {
  /** Vertices as interleaved x, y. */
  vertices: Float64Array;
  /** Centreline segments as interleaved x1, y1, x2, y2. */
  segments: Float64Array;
  /** The plan's text labels (TEXT, MTEXT, ATTRIB) at their anchor points, text as a station id (stationOf). */
  labels: { x: number; y: number; text: string }[];
}

/** The longest survey station id the API stores (``STATION_MAX_CHARS`` in formats/records.py). */
export const STATION_MAX_CHARS = 64;

/** A label's text as a station id: whitespace and control characters collapsed to one space, trimmed; null
 * when blank or longer than the API stores. */
export function stationOf(text: string): string | null {
  const station = text.replace(/[\s\p{Cc}]+/gu, " ").trim();
  return station !== "" && station.length <= STATION_MAX_CHARS ? station : null;
}

export type SnapResult =
  | { x: number; y: number; kind: "vertex" | "centreline" | "none" }
  | { x: number; y: number; kind: "label"; station: string };

/** The closest point of segment (ax, ay)-(bx, by) to (x, y). */
export function closestOnSegment(
  x: number,
  y: number,
  ax: number,
  ay: number,
  bx: number,
  by: number,
): [number, number] {
  const dx = bx - ax;
  const dy = by - ay;
  const length2 = dx * dx + dy * dy;
  const u = length2 > 0 ? Math.min(1, Math.max(0, ((x - ax) * dx + (y - ay) * dy) / length2)) : 0;
  return [ax + u * dx, ay + u * dy];
}

export function snapPoint(targets: SnapTargets, x: number, y: number, toleranceM: number): SnapResult {
  let best = toleranceM;
  let found: SnapResult = { x, y, kind: "none" };
  const v = targets.vertices;
  for (let i = 0; i + 1 < v.length; i += 2) {
    const d = Math.hypot(v[i]! - x, v[i + 1]! - y);
    if (d <= best) {
      best = d;
      found = { x: v[i]!, y: v[i + 1]!, kind: "vertex" };
    }
  }
  for (const label of targets.labels) {
    const d = Math.hypot(label.x - x, label.y - y);
    if (d <= best) {
      best = d;
      found = { x: label.x, y: label.y, kind: "label", station: label.text };
    }
  }
  if (found.kind !== "none") return found;
  const s = targets.segments;
  for (let i = 0; i + 3 < s.length; i += 4) {
    const [px, py] = closestOnSegment(x, y, s[i]!, s[i + 1]!, s[i + 2]!, s[i + 3]!);
    const d = Math.hypot(px - x, py - y);
    if (d <= best) {
      best = d;
      found = { x: px, y: py, kind: "centreline" };
    }
  }
  return found;
}

/**
 * Vertices and (for centreline layers) segments of GeoJSON line geometries, Points whose
 * ``properties.text`` makes a station id as labels and other Points (the DXF's POINTs, long texts) as vertices, in world coordinates.
 */
export function snapTargetsOf(layers: Record<string, unknown>, isCentreline: (name: string) => boolean): SnapTargets {
  const vertices: number[] = [];
  const segments: number[] = [];
  const labels: SnapTargets["labels"] = [];
  const lines = (coordinates: unknown, depth: number): number[][][] => {
    if (!Array.isArray(coordinates)) return [];
    if (depth === 0) return [coordinates as number[][]];
    return coordinates.flatMap((c) => lines(c, depth - 1));
  };
  for (const [name, collection] of Object.entries(layers)) {
    const features =
      (
        collection as {
          features?: {
            geometry?: { type?: string; coordinates?: unknown } | null;
            properties?: { text?: unknown } | null;
          }[];
        }
      ).features ?? [];
    for (const f of features) {
      const g = f.geometry;
      if (!g) continue;
      const depth = g.type === "LineString" ? 0 : g.type === "MultiLineString" || g.type === "Polygon" ? 1 : -1;
      if (g.type === "Point" && Array.isArray(g.coordinates)) {
        const [x, y] = [Number(g.coordinates[0]), Number(g.coordinates[1])];
        const text = f.properties?.text;
        const station = typeof text === "string" ? stationOf(text) : null;
        if (station !== null) labels.push({ x, y, text: station });
        else vertices.push(x, y);
        continue;
      }
      if (depth < 0) continue;
      for (const line of lines(g.coordinates, depth)) {
        line.forEach((p, i) => {
          vertices.push(p[0]!, p[1]!);
          const q = line[i + 1];
          if (q && isCentreline(name)) segments.push(p[0]!, p[1]!, q[0]!, q[1]!);
        });
      }
    }
  }
  return { vertices: Float64Array.from(vertices), segments: Float64Array.from(segments), labels };
}

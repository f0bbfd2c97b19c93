// A survey layer's lines as one flat coordinate array for a single OpenLayers MultiLineString: a plan of 100,000
// separate LINE entities drawn as 100,000 features costs the map a feature's bookkeeping each (building,
// hit-detection replays), while one multi-line geometry per layer draws the same strokes at a fraction of the
// cost. Survey lines are not picked on the map (snapping works on the layers' own coordinates), so nothing is lost.

export interface FlatLines {
  /** x0, y0, x1, y1, ... of every part, shifted to the local origin (metres). */
  flat: number[];
  /** Index into ``flat`` where each part ends (OpenLayers' ``ends``). */
  ends: number[];
  /** Features of the collection that contributed at least one line. */
  features: number;
}

interface GeometryLike {
  type?: string;
  coordinates?: unknown;
}

/**
 * Every line of a GeoJSON-like FeatureCollection (LineString, MultiLineString, and the rings of Polygon and
 * MultiPolygon outlines) shifted by ``(-x0, -y0)``; points and texts are left out, as are parts with fewer than
 * two vertices.
 */
export function flattenLines(collection: unknown, x0: number, y0: number): FlatLines {
  const flat: number[] = [];
  const ends: number[] = [];
  let features = 0;
  const part = (coords: unknown): boolean => {
    if (!Array.isArray(coords) || coords.length < 2) return false;
    const start = flat.length;
    for (const c of coords as unknown[]) {
      if (!Array.isArray(c) || typeof c[0] !== "number" || typeof c[1] !== "number") continue;
      flat.push(c[0] - x0, c[1] - y0);
    }
    if (flat.length - start < 4) {
      flat.length = start;
      return false;
    }
    ends.push(flat.length);
    return true;
  };
  const list = (collection as { features?: { geometry?: GeometryLike | null }[] } | null)?.features ?? [];
  for (const feature of list) {
    const g = feature.geometry;
    if (!g || !Array.isArray(g.coordinates)) continue;
    const c = g.coordinates as unknown[];
    let drew = false;
    if (g.type === "LineString") drew = part(c);
    else if (g.type === "MultiLineString" || g.type === "Polygon") for (const p of c) drew = part(p) || drew;
    else if (g.type === "MultiPolygon")
      for (const poly of c) for (const ring of poly as unknown[]) drew = part(ring) || drew;
    if (drew) features += 1;
  }
  return { flat, ends, features };
}

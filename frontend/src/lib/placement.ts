// Checks before a surveyed point is written for a keyframe: a point far from the keyframe's current estimate,
// or outside the plan's walls, is more likely a stray click than a survey, so the UI asks first. Mine-grid metres.

/** A grounding this far (metres) from its keyframe's current estimate needs a confirmation. */
export const FAR_FROM_ESTIMATE_M = 15;

/** Closed wall outlines, each as interleaved x, y (the closing vertex need not repeat the first). */
export type WallRings = Float64Array[];

interface FeatureLike {
  geometry?: { type?: string; coordinates?: unknown } | null;
  properties?: Record<string, unknown> | null;
}

const CLOSED_EPS_M = 1e-6;

function ringOf(coordinates: unknown, closed: boolean): Float64Array | null {
  if (!Array.isArray(coordinates) || coordinates.length < 3) return null;
  const points = coordinates as number[][];
  const first = points[0]!;
  const last = points[points.length - 1]!;
  const shut = closed || Math.hypot(first[0]! - last[0]!, first[1]! - last[1]!) < CLOSED_EPS_M;
  return shut ? Float64Array.from(points.flatMap((p) => [p[0]!, p[1]!])) : null;
}

/**
 * The closed outlines of the layers ``isWall`` names (GeoJSON-like FeatureCollections, as the survey API
 * answers): closed LineStrings (``properties.closed`` or the first vertex repeated) and Polygon rings.
 */
export function wallRingsOf(layers: Record<string, unknown>, isWall: (name: string) => boolean): WallRings {
  const rings: WallRings = [];
  for (const [name, collection] of Object.entries(layers)) {
    if (!isWall(name)) continue;
    for (const f of (collection as { features?: FeatureLike[] }).features ?? []) {
      const g = f.geometry;
      if (!g) continue;
      const closed = f.properties?.closed === true;
      const parts =
        g.type === "LineString"
          ? [g.coordinates]
          : g.type === "Polygon" || g.type === "MultiLineString"
            ? g.coordinates
            : [];
      for (const part of Array.isArray(parts) ? parts : []) {
        const ring = ringOf(part, closed || g.type === "Polygon");
        if (ring) rings.push(ring);
      }
    }
  }
  return rings;
}

/** Whether (x, y) lies inside the walls: inside an odd number of rings (the outline, not a pillar in it). */
export function insideRings(x: number, y: number, rings: WallRings): boolean {
  let inside = false;
  for (const r of rings) {
    const n = r.length / 2;
    for (let i = 0, j = n - 1; i < n; j = i++) {
      const xi = r[2 * i]!;
      const yi = r[2 * i + 1]!;
      const xj = r[2 * j]!;
      const yj = r[2 * j + 1]!;
      if (yi > y !== yj > y && x < xi + ((y - yi) * (xj - xi)) / (yj - yi)) inside = !inside;
    }
  }
  return inside;
}

export interface PlacementCheck {
  /** Metres from the keyframe's current estimate; null without an estimate. */
  distanceM: number | null;
  /** Whether the point lies inside the walls; null when the plan has no closed walls. */
  insideWalls: boolean | null;
  /** Why to ask before writing it (empty: write it straight away). */
  warnings: string[];
}

/** What is doubtful about grounding a keyframe at (x, y), given its ``estimate`` and the plan's ``walls``. */
export function checkPlacement(
  x: number,
  y: number,
  estimate: readonly [number, number] | null,
  walls: WallRings | null,
  farM = FAR_FROM_ESTIMATE_M,
): PlacementCheck {
  const distanceM = estimate ? Math.hypot(x - estimate[0], y - estimate[1]) : null;
  const insideWalls = walls && walls.length > 0 ? insideRings(x, y, walls) : null;
  const warnings: string[] = [];
  if (distanceM !== null && distanceM > farM)
    warnings.push(`${distanceM.toFixed(1)} m from the keyframe's current estimate (more than ${farM} m)`);
  if (insideWalls === false) warnings.push("outside the plan's walls");
  return { distanceM, insideWalls, warnings };
}

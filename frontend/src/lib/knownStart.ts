// Placing a vehicle's known start: the radius the surveyor types, the request body from a map click (survey
// coordinates: the map's local origin is already added back) and the wording of the server's answer.
import { formatGrid } from "./localOrigin";

export const DEFAULT_START_RADIUS_M = 10;

/** A radius typed in metres: a finite number, zero (the nearest map node only) or more; else null. */
export function parseRadiusM(text: string): number | null {
  const s = text.trim();
  if (!/^\+?(\d+(\.\d*)?|\.\d+)$/.test(s)) return null;
  const value = Number(s);
  return Number.isFinite(value) && value >= 0 ? value : null;
}

export interface StartBody {
  x: number;
  y: number;
  radius_m: number;
}

/** The body of ``POST /api/vehicles/{id}/start`` for a click at survey ``(x, y)``; null when the radius is bad. */
export function startBody(x: number, y: number, radiusText: string): StartBody | null {
  const radius = parseRadiusM(radiusText);
  return radius === null ? null : { x, y, radius_m: radius };
}

/** "Start set at E 12.30  N 45.60 ± 10 m (node 7)". */
export function describeStart(answer: { x: number; y: number; radius_m: number; node: number }): string {
  return `Start set at ${formatGrid(answer.x, answer.y, 1)} ± ${answer.radius_m} m (node ${answer.node})`;
}

// Heading and motion for people and for the map: the server's yaw (radians, survey frame, counter-clockwise
// from +x = east) as an OpenLayers rotation and a grid bearing; speed and moving/stopped, "—" when unknown.

const TWO_PI = 2 * Math.PI;
const COMPASS = ["N", "NE", "E", "SE", "S", "SW", "W", "NW"];
export const UNKNOWN = "—";

function wrap(angleRad: number): number {
  const a = angleRad % TWO_PI;
  return a < 0 ? a + TWO_PI : a;
}

/**
 * The OpenLayers rotation (radians, clockwise, in [0, 2π)) of a marker drawn pointing up (north) so that it
 * points along ``yawRad`` (counter-clockwise from east): east is a quarter turn clockwise from north.
 */
export function yawToRotation(yawRad: number): number {
  return wrap(Math.PI / 2 - yawRad);
}

/** Grid bearing in whole degrees clockwise from grid north, 0..359. */
export function bearingDeg(yawRad: number): number {
  return Math.round((wrap(Math.PI / 2 - yawRad) * 180) / Math.PI) % 360;
}

/** "045° NE" (grid bearing and compass point), or "—" when the heading is unknown. */
export function formatBearing(yawRad: number | null | undefined): string {
  if (yawRad === null || yawRad === undefined || !Number.isFinite(yawRad)) return UNKNOWN;
  const deg = bearingDeg(yawRad);
  return `${String(deg).padStart(3, "0")}° ${COMPASS[Math.round(deg / 45) % 8]}`;
}

/** "1.4 m/s", "0.8 m/s reversing" (a negative speed), or "—" when the server does not know the speed. */
export function formatSpeed(speedMps: number | null | undefined): string {
  if (speedMps === null || speedMps === undefined || !Number.isFinite(speedMps)) return UNKNOWN;
  const text = `${Math.abs(speedMps).toFixed(1)} m/s`;
  return speedMps < 0 && text !== "0.0 m/s" ? `${text} reversing` : text;
}

/** "moving" / "stopped", or "—" when the server does not know. */
export function formatMotion(moving: boolean | null | undefined): string {
  return moving === true ? "moving" : moving === false ? "stopped" : UNKNOWN;
}

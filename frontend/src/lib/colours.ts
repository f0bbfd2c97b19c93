// Colour scales shared by the views (dark theme).

export type Rgb = [number, number, number];

const RED: Rgb = [229, 72, 77];
const AMBER: Rgb = [240, 180, 41];
const GREEN: Rgb = [48, 196, 120];
export const STALE_GREY: Rgb = [120, 126, 134];

function mix(a: Rgb, b: Rgb, t: number): Rgb {
  return [0, 1, 2].map((i) => Math.round(a[i]! + (b[i]! - a[i]!) * t)) as Rgb;
}

export function rgbCss(c: Rgb, alpha = 1): string {
  return alpha >= 1 ? `rgb(${c[0]}, ${c[1]}, ${c[2]})` : `rgba(${c[0]}, ${c[1]}, ${c[2]}, ${alpha})`;
}

/** Confidence 0..1 -> red (0) .. amber (0.5) .. green (1); clamped; NaN counts as 0. */
export function confidenceColour(confidence: number): Rgb {
  const c = Number.isFinite(confidence) ? Math.min(1, Math.max(0, confidence)) : 0;
  return c < 0.5 ? mix(RED, AMBER, c / 0.5) : mix(AMBER, GREEN, (c - 0.5) / 0.5);
}

/** Residual class of a grounding: good under ``good_m``, fair under ``bad_m``, else bad. */
export type ResidualClass = "good" | "fair" | "bad" | "none";

export function residualClass(distanceM: number | null | undefined, goodM = 0.5, badM = 2.0): ResidualClass {
  if (distanceM === null || distanceM === undefined || !Number.isFinite(distanceM)) return "none";
  if (distanceM < goodM) return "good";
  if (distanceM < badM) return "fair";
  return "bad";
}

const DRIVE_PALETTE: Rgb[] = [
  [77, 171, 247],
  [255, 146, 43],
  [151, 117, 250],
  [56, 217, 169],
  [247, 103, 7],
  [240, 101, 149],
  [132, 94, 247],
  [192, 235, 117],
];

/** A distinct colour per drive id (cycles after eight). */
export function driveColour(driveId: number): Rgb {
  const n = DRIVE_PALETTE.length;
  return DRIVE_PALETTE[(((driveId - 1) % n) + n) % n]!;
}

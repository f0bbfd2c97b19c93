// Colour scales shared by the views (dark theme); the confidence bands are in confidence.ts.

export type Rgb = [number, number, number];

export const STALE_GREY: Rgb = [120, 126, 134];

export function rgbCss(c: Rgb, alpha = 1): string {
  return alpha >= 1 ? `rgb(${c[0]}, ${c[1]}, ${c[2]})` : `rgba(${c[0]}, ${c[1]}, ${c[2]}, ${alpha})`;
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

// One confidence, shown the same way everywhere in the monitoring view: the server's calibrated probability
// that a position is right, as a whole percentage and in bands (marker, trail, vehicle list, details, legend).
import { type Rgb, rgbCss, STALE_GREY } from "./colours";

/** A position at least this likely to be right is drawn as confident. */
export const CONFIDENT_PCT = 90;
/** Below ``CONFIDENT_PCT`` and at least this: uncertain; below it: doubtful. */
export const UNCERTAIN_PCT = 50;

export type ConfidenceBand = "confident" | "uncertain" | "doubtful" | "lost" | "stale";

export const BAND_COLOURS: Record<ConfidenceBand, Rgb> = {
  confident: [48, 196, 120],
  uncertain: [240, 180, 41],
  doubtful: [229, 72, 77],
  lost: [214, 51, 168],
  stale: STALE_GREY,
};

/** The legend's wording, in the legend's order. */
export const BAND_LABELS: [ConfidenceBand, string][] = [
  ["confident", `confident (≥ ${CONFIDENT_PCT} %)`],
  ["uncertain", `uncertain (${UNCERTAIN_PCT}–${CONFIDENT_PCT - 1} %)`],
  ["doubtful", `doubtful (< ${UNCERTAIN_PCT} %)`],
  ["lost", "lost"],
  ["stale", "stale (no recent position)"],
];

/**
 * A probability 0..1 as a whole percentage, rounded down (so "90 %" is never shown for 0.899, which is not
 * confident); clamped to 0..100, NaN counts as 0. The bands are cut on this number, so the shown value and
 * the colour always agree.
 */
export function confidencePercent(confidence: number): number {
  if (!Number.isFinite(confidence)) return 0;
  return Math.min(100, Math.max(0, Math.floor(confidence * 100 + 1e-9)));
}

/** "93 %", or "—" without a value. */
export function formatConfidence(confidence: number | null | undefined): string {
  return confidence === null || confidence === undefined ? "—" : `${confidencePercent(confidence)} %`;
}

/** The band of a position: stale and lost win over the confidence. */
export function confidenceBand(confidence: number, lost: boolean, stale = false): ConfidenceBand {
  if (stale) return "stale";
  if (lost) return "lost";
  const pct = confidencePercent(confidence);
  if (pct >= CONFIDENT_PCT) return "confident";
  return pct >= UNCERTAIN_PCT ? "uncertain" : "doubtful";
}

export function bandCss(band: ConfidenceBand, alpha = 1): string {
  return rgbCss(BAND_COLOURS[band], alpha);
}

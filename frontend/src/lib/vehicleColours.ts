// One colour per vehicle on the monitoring page (its trail, its name on the plan, its swatch in the list and the
// details), next to the confidence band (the marker's fill, lib/confidence.ts). The colour comes from the vehicle
// id, so it is the same on every screen and after a reload; the palette leaves out the bands' green, red, magenta
// and grey, so a trail never reads as a confidence.
import { BAND_COLOURS, type ConfidenceBand } from "./confidence";
import { type Rgb, rgbCss } from "./colours";

/** Distinguishable on the dark plan and from the band colours; vehicle ids cycle through it. */
export const VEHICLE_PALETTE: readonly Rgb[] = [
  [77, 171, 247], // blue
  [253, 126, 20], // orange
  [151, 117, 250], // violet
  [21, 190, 200], // teal-cyan
  [250, 162, 193], // pink
  [210, 160, 110], // tan
  [192, 235, 117], // pale lime
  [233, 236, 239], // white
];

/** The colour of a vehicle id: ``id - 1`` modulo the palette, so consecutive ids differ. */
export function vehicleColour(vehicleId: number): Rgb {
  const n = VEHICLE_PALETTE.length;
  const i = Math.trunc(vehicleId) - 1;
  return VEHICLE_PALETTE[Number.isFinite(i) ? ((i % n) + n) % n : 0]!;
}

export function vehicleCss(vehicleId: number, alpha = 1): string {
  return rgbCss(vehicleColour(vehicleId), alpha);
}

/** How a stretch of trail is stroked: the vehicle's colour, its confidence in the dash. */
export interface TrailStroke {
  colour: string;
  /** Dash and gap in pixels; undefined for a solid line. */
  dash: number[] | undefined;
}

/** The dash of each band: solid only when confident; a stale trail is grey whatever the band was. */
export const TRAIL_DASH: Record<ConfidenceBand, number[] | undefined> = {
  confident: undefined,
  uncertain: [10, 5],
  doubtful: [4, 5],
  lost: [1, 6],
  stale: [6, 4],
};

/** The legend's wording of the trail's dashes, in the legend's order. */
export const TRAIL_LABELS: [ConfidenceBand, string][] = [
  ["confident", "solid: confident"],
  ["uncertain", "dashed: uncertain"],
  ["doubtful", "short dashes: doubtful"],
  ["lost", "dotted: lost"],
];

/** The stroke of a run of one band of vehicle ``vehicleId``'s trail. */
export function trailStroke(vehicleId: number, band: ConfidenceBand): TrailStroke {
  const colour = band === "stale" ? rgbCss(BAND_COLOURS.stale, 0.5) : vehicleCss(vehicleId, 0.9);
  return { colour, dash: TRAIL_DASH[band] };
}

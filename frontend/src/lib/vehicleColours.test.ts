import { describe, expect, it } from "vitest";
import { BAND_COLOURS, type ConfidenceBand } from "./confidence";
import { rgbCss } from "./colours";
import { TRAIL_DASH, trailStroke, VEHICLE_PALETTE, vehicleColour, vehicleCss } from "./vehicleColours";

const distance = (a: readonly number[], b: readonly number[]) => Math.hypot(...a.map((v, i) => v - b[i]!));

describe("vehicle colours", () => {
  it("gives consecutive ids different colours and repeats after the palette", () => {
    const n = VEHICLE_PALETTE.length;
    const firsts = Array.from({ length: n }, (_, i) => rgbCss(vehicleColour(i + 1)));
    expect(new Set(firsts).size).toBe(n);
    expect(vehicleColour(1)).toEqual(VEHICLE_PALETTE[0]);
    expect(vehicleColour(n + 3)).toEqual(vehicleColour(3));
  });

  it("is a function of the id alone (the same after a reload) and never undefined", () => {
    expect(vehicleCss(42)).toBe(vehicleCss(42));
    for (const id of [0, -1, -9, 1.5, NaN, 1e9]) expect(VEHICLE_PALETTE).toContainEqual(vehicleColour(id));
    expect(vehicleCss(2, 0.5)).toMatch(/^rgba\(/);
  });

  it("keeps the palette apart from itself and from the band colours", () => {
    const MIN_APART = 60; // RGB distance: told apart at a glance on the dark plan
    for (const [i, a] of VEHICLE_PALETTE.entries()) {
      for (const b of VEHICLE_PALETTE.slice(i + 1)) expect(distance(a, b)).toBeGreaterThan(MIN_APART);
      for (const band of ["confident", "doubtful", "lost", "stale"] as const)
        expect(distance(a, BAND_COLOURS[band])).toBeGreaterThan(MIN_APART);
    }
  });
});

describe("trail strokes", () => {
  it("draws a trail in its vehicle's colour, solid only when confident", () => {
    const bands: ConfidenceBand[] = ["confident", "uncertain", "doubtful", "lost"];
    for (const band of bands) expect(trailStroke(3, band).colour).toBe(vehicleCss(3, 0.9));
    expect(trailStroke(3, "confident").dash).toBeUndefined();
    const dashes = bands.slice(1).map((b) => JSON.stringify(trailStroke(3, b).dash));
    expect(dashes.every((d) => d !== undefined)).toBe(true);
    expect(new Set(dashes).size).toBe(dashes.length); // each band its own dash
    expect(trailStroke(1, "uncertain").colour).not.toBe(trailStroke(2, "uncertain").colour);
  });

  it("greys a stale trail whatever the vehicle", () => {
    expect(trailStroke(1, "stale")).toEqual(trailStroke(2, "stale"));
    expect(trailStroke(1, "stale").colour).toBe(rgbCss(BAND_COLOURS.stale, 0.5));
    expect(TRAIL_DASH.stale).toBeDefined();
  });
});

import { describe, expect, it } from "vitest";
import { checkPlacement, FAR_FROM_ESTIMATE_M, insideRings, wallRingsOf } from "./placement";

// a 100 x 20 m tunnel outline with a 10 x 10 m pillar inside it
const OUTLINE = [
  [0, 0],
  [100, 0],
  [100, 20],
  [0, 20],
  [0, 0],
];
const PILLAR = [
  [40, 5],
  [50, 5],
  [50, 15],
  [40, 15],
];
const layers = {
  WALLS: {
    features: [
      { geometry: { type: "LineString", coordinates: OUTLINE }, properties: {} },
      { geometry: { type: "LineString", coordinates: PILLAR }, properties: { closed: true } },
      {
        geometry: {
          type: "LineString",
          coordinates: [
            [0, 50],
            [10, 50],
          ],
        },
        properties: {},
      }, // open: not a ring
    ],
  },
  CENTRELINE: { features: [{ geometry: { type: "LineString", coordinates: OUTLINE }, properties: {} }] },
};
const walls = wallRingsOf(layers, (name) => /wall/i.test(name));

describe("wall rings", () => {
  it("keeps the closed outlines of the wall layers only", () => {
    expect(walls).toHaveLength(2);
    expect(Array.from(walls[1]!)).toEqual([40, 5, 50, 5, 50, 15, 40, 15]);
  });

  it("is inside the outline, outside it and inside the pillar (rock) by the even-odd rule", () => {
    expect(insideRings(10, 10, walls)).toBe(true);
    expect(insideRings(45, 10, walls)).toBe(false); // in the pillar
    expect(insideRings(10, 30, walls)).toBe(false);
    expect(insideRings(-1, 10, walls)).toBe(false);
  });
});

describe("checkPlacement", () => {
  it("writes a point near the estimate and inside the walls without asking", () => {
    const check = checkPlacement(12, 10, [10, 10], walls);
    expect(check.distanceM).toBeCloseTo(2);
    expect(check.insideWalls).toBe(true);
    expect(check.warnings).toEqual([]);
  });

  it("asks for a point further than the set distance from the estimate", () => {
    const check = checkPlacement(10 + FAR_FROM_ESTIMATE_M + 1, 10, [10, 10], walls);
    expect(check.warnings).toEqual([
      `16.0 m from the keyframe's current estimate (more than ${FAR_FROM_ESTIMATE_M} m)`,
    ]);
    expect(checkPlacement(10 + FAR_FROM_ESTIMATE_M, 10, [10, 10], walls).warnings).toEqual([]);
  });

  it("asks for a point in the rock, and names both reasons when both hold", () => {
    expect(checkPlacement(45, 10, [44, 10], walls).warnings).toEqual(["outside the plan's walls"]);
    expect(checkPlacement(10, 60, [10, 10], walls).warnings).toHaveLength(2);
  });

  it("checks nothing it cannot know: no estimate (no map yet), no closed walls", () => {
    const check = checkPlacement(500, 500, null, []);
    expect(check).toEqual({ distanceM: null, insideWalls: null, warnings: [] });
  });
});

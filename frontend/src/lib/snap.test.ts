import { describe, expect, it } from "vitest";
import { closestOnSegment, snapPoint, snapTargetsOf } from "./snap";

const layers = {
  WALLS: {
    type: "FeatureCollection",
    features: [
      {
        geometry: {
          type: "LineString",
          coordinates: [
            [0, 0],
            [10, 0],
            [10, 10],
          ],
        },
      },
    ],
  },
  CENTRELINE: {
    type: "FeatureCollection",
    features: [
      {
        geometry: {
          type: "LineString",
          coordinates: [
            [0, 5],
            [20, 5],
          ],
        },
      },
    ],
  },
};
const targets = snapTargetsOf(layers, (n) => /centre|center/i.test(n));

describe("snapping", () => {
  it("collects vertices of every layer and segments of centrelines only", () => {
    expect(Array.from(targets.vertices)).toEqual([0, 0, 10, 0, 10, 10, 0, 5, 20, 5]);
    expect(Array.from(targets.segments)).toEqual([0, 5, 20, 5]);
  });

  it("prefers a vertex within tolerance", () => {
    expect(snapPoint(targets, 10.3, 0.2, 1)).toEqual({ x: 10, y: 0, kind: "vertex" });
  });

  it("falls back to the nearest point on a centreline", () => {
    expect(snapPoint(targets, 14, 5.4, 1)).toEqual({ x: 14, y: 5, kind: "centreline" });
  });

  it("keeps the click when nothing is near", () => {
    expect(snapPoint(targets, 5, 2.5, 1)).toEqual({ x: 5, y: 2.5, kind: "none" });
  });

  it("clamps to segment ends", () => {
    expect(closestOnSegment(-5, 3, 0, 0, 10, 0)).toEqual([0, 0]);
    expect(closestOnSegment(15, 3, 0, 0, 10, 0)).toEqual([10, 0]);
    expect(closestOnSegment(1, 1, 2, 2, 2, 2)).toEqual([2, 2]);
  });
});

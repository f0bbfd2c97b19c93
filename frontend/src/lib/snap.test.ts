import { describe, expect, it } from "vitest";
import { STATION_MAX_CHARS, closestOnSegment, snapPoint, snapTargetsOf, stationOf } from "./snap";

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

const point = (x: number, y: number, properties: Record<string, unknown>) => ({
  geometry: { type: "Point", coordinates: [x, y] },
  properties,
});
const labelled = snapTargetsOf(
  {
    ...layers,
    LABELS: {
      type: "FeatureCollection",
      features: [
        point(10.6, 0, { entity: "TEXT", text: "  STN-104 " }),
        point(14, 8, { entity: "MTEXT", text: "STN\n105" }),
        point(3, 3, { entity: "TEXT", text: "   " }),
        point(18, 0, { entity: "TEXT", text: "x".repeat(STATION_MAX_CHARS + 1) }),
      ],
    },
    POINTS: { type: "FeatureCollection", features: [point(6, 6, { entity: "POINT" })] },
  },
  (n) => /centre|center/i.test(n),
);

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

  it("keeps labels with their station text apart and snaps POINTs, blank and overlong texts as vertices", () => {
    expect(labelled.labels).toEqual([
      { x: 10.6, y: 0, text: "STN-104" },
      { x: 14, y: 8, text: "STN 105" },
    ]);
    expect(Array.from(labelled.vertices.slice(10))).toEqual([3, 3, 18, 0, 6, 6]);
  });

  it("snaps to a label's anchor with its trimmed text when the label is nearer than any vertex", () => {
    expect(snapPoint(labelled, 10.5, 0.1, 1)).toEqual({ x: 10.6, y: 0, kind: "label", station: "STN-104" });
  });

  it("prefers a nearer vertex to a label", () => {
    expect(snapPoint(labelled, 10.2, 0, 1)).toEqual({ x: 10, y: 0, kind: "vertex" });
  });

  it("takes a label only within tolerance, and before a centreline", () => {
    expect(snapPoint(labelled, 14, 6.5, 1)).toEqual({ x: 14, y: 6.5, kind: "none" });
    expect(snapPoint(labelled, 14, 6.5, 2)).toEqual({ x: 14, y: 8, kind: "label", station: "STN 105" });
    expect(snapPoint(labelled, 14, 6.5, 2.5).kind).toBe("label"); // the centreline, as near, comes after points
  });

  it("makes station ids of single-line texts within the API's length", () => {
    expect(stationOf(" A\t1 ")).toBe("A 1");
    expect(stationOf("\n")).toBeNull();
    expect(stationOf("y".repeat(STATION_MAX_CHARS))).toHaveLength(STATION_MAX_CHARS);
    expect(stationOf("y".repeat(STATION_MAX_CHARS + 1))).toBeNull();
  });
});

import { describe, expect, it } from "vitest";
import { flattenLines } from "./surveyLines";

const line = (coordinates: number[][]) => ({ geometry: { type: "LineString", coordinates } });

describe("survey lines as one multi-line", () => {
  it("concatenates lines, multi-lines and polygon rings, shifted to the origin", () => {
    const collection = {
      features: [
        line([
          [100, 200],
          [110, 200],
        ]),
        {
          geometry: {
            type: "MultiLineString",
            coordinates: [
              [
                [100, 200],
                [100, 210],
                [105, 215],
              ],
              [
                [0, 0],
                [1, 1],
              ],
            ],
          },
        },
        {
          geometry: {
            type: "Polygon",
            coordinates: [
              [
                [100, 200],
                [101, 200],
                [101, 201],
                [100, 200],
              ],
            ],
          },
        },
      ],
    };
    const out = flattenLines(collection, 100, 200);
    expect(out.flat).toEqual([0, 0, 10, 0, 0, 0, 0, 10, 5, 15, -100, -200, -99, -199, 0, 0, 1, 0, 1, 1, 0, 0]);
    expect(out.ends).toEqual([4, 10, 14, 22]);
    expect(out.features).toBe(3);
  });

  it("leaves out points, texts, degenerate parts and missing geometries", () => {
    const collection = {
      features: [
        { geometry: { type: "Point", coordinates: [5, 5] } },
        { geometry: null },
        line([[1, 1]]),
        {
          geometry: {
            type: "LineString",
            coordinates: [
              [1, 1],
              ["x", 2],
            ],
          },
        },
        line([
          [0, 0],
          [3, 4],
        ]),
      ],
    };
    const out = flattenLines(collection, 0, 0);
    expect(out.flat).toEqual([0, 0, 3, 4]);
    expect(out.ends).toEqual([4]);
    expect(out.features).toBe(1);
    expect(flattenLines({}, 0, 0)).toEqual({ flat: [], ends: [], features: 0 });
  });
});

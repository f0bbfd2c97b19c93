import { describe, expect, it } from "vitest";
import { LABEL_HEIGHT_M, MAX_LABEL_PX, labelFontPx, labelsOf } from "./surveyLabels";

const collection = {
  type: "FeatureCollection",
  features: [
    {
      geometry: { type: "Point", coordinates: [1010, 2020] },
      properties: { entity: "TEXT", text: " Stope 4 ", height_m: 1.5 },
    },
    { geometry: { type: "Point", coordinates: [1000, 2000] }, properties: { entity: "MTEXT", text: "Sump\nNorth" } },
    { geometry: { type: "Point", coordinates: [1000, 2000] }, properties: { entity: "POINT" } },
    { geometry: { type: "Point", coordinates: [1000, 2000] }, properties: { entity: "TEXT", text: "  " } },
    {
      geometry: {
        type: "LineString",
        coordinates: [
          [0, 0],
          [1, 1],
        ],
      },
      properties: { text: "not a point" },
    },
  ],
};

describe("labelsOf", () => {
  it("keeps the texts of points, shifted to the local origin", () => {
    expect(labelsOf(collection, 1000, 2000)).toEqual([
      { text: "Stope 4", x: 10, y: 20, heightM: 1.5 },
      { text: "Sump\nNorth", x: 0, y: 0, heightM: LABEL_HEIGHT_M },
    ]);
  });

  it("reads nothing from what is not a collection", () => {
    expect(labelsOf(null, 0, 0)).toEqual([]);
    expect(labelsOf({}, 0, 0)).toEqual([]);
  });
});

describe("labelFontPx", () => {
  it("follows the zoom: the label keeps its height in metres", () => {
    expect(labelFontPx(LABEL_HEIGHT_M / 12)).toBe(12);
    expect(labelFontPx(LABEL_HEIGHT_M / 10)).toBe(10);
    expect(labelFontPx(0.1, 1.5)).toBe(15);
  });

  it("stops growing close up and is left out far away", () => {
    expect(labelFontPx(0.001)).toBe(MAX_LABEL_PX);
    expect(labelFontPx(LABEL_HEIGHT_M / 5)).toBeNull();
    expect(labelFontPx(0)).toBeNull();
  });
});

import { describe, expect, it } from "vitest";
import { FIT, MAX_SCALE, panBy, zoomAt } from "./zoomView";

const W = 640;
const H = 480;

describe("zoomAt", () => {
  it("keeps the point under the pointer where it was", () => {
    const v = zoomAt(FIT, 2, 160, 120, W, H);
    expect(v).toEqual({ scale: 2, x: -160, y: -120 });
    // the image point under (160, 120): (160 - x) / scale, the same before and after
    expect((160 - v.x) / v.scale).toBeCloseTo(160);
    const w = zoomAt(v, 1.5, 300, 200, W, H);
    expect((300 - w.x) / w.scale).toBeCloseTo((300 - v.x) / v.scale);
  });

  it("stays between the fitted size and the largest zoom", () => {
    expect(zoomAt(FIT, 0.5, 100, 100, W, H)).toEqual(FIT);
    expect(zoomAt(FIT, 100, 0, 0, W, H).scale).toBe(MAX_SCALE);
  });
});

describe("panBy", () => {
  it("moves the zoomed image without leaving an empty margin", () => {
    const v = zoomAt(FIT, 2, 0, 0, W, H);
    expect(panBy(v, -100, -50, W, H)).toEqual({ scale: 2, x: -100, y: -50 });
    expect(panBy(v, 100, 100, W, H)).toEqual({ scale: 2, x: 0, y: 0 });
    expect(panBy(v, -10000, -10000, W, H)).toEqual({ scale: 2, x: -W, y: -H });
    expect(panBy(FIT, 30, 30, W, H)).toEqual(FIT);
  });
});

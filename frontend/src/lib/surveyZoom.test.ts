import { describe, expect, it } from "vitest";
import { serverZoomFor } from "./surveyZoom";

describe("serverZoomFor", () => {
  it("is 0 while the plan spans at most 256 px", () => {
    expect(serverZoomFor(2000, 10)).toBe(0); // 200 px
    expect(serverZoomFor(2560, 10)).toBe(0); // exactly 256 px
  });

  it("doubles the detail per halving of the resolution", () => {
    expect(serverZoomFor(2000, 2)).toBe(2); // 1000 px -> 256 * 4 = 1024
    expect(serverZoomFor(2000, 1)).toBe(3); // 2000 px -> 2048
    expect(serverZoomFor(2000, 0.5)).toBe(4);
  });

  it("clamps and survives degenerate input", () => {
    expect(serverZoomFor(2000, 1e-9)).toBe(30);
    expect(serverZoomFor(0, 1)).toBe(0);
    expect(serverZoomFor(100, 0)).toBe(0);
  });
});

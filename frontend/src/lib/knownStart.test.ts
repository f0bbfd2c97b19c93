import { describe, expect, it } from "vitest";
import { detailText } from "../api/client";
import { describeStart, parseRadiusM, startBody } from "./knownStart";

describe("placing a known start", () => {
  it("takes a radius of zero metres or more (the server sets the upper bound)", () => {
    expect(parseRadiusM("10")).toBe(10);
    expect(parseRadiusM(" 2.5 ")).toBe(2.5);
    expect(parseRadiusM(".5")).toBe(0.5);
    expect(parseRadiusM("0")).toBe(0);
    for (const bad of ["", "-3", "abc", "1e3", "Infinity", "10 m"]) expect(parseRadiusM(bad)).toBeNull();
  });

  it("sends the clicked survey coordinates with the radius", () => {
    expect(startBody(13702.1, 56911.4, "10")).toEqual({ x: 13702.1, y: 56911.4, radius_m: 10 });
    expect(startBody(1, 2, "-1")).toBeNull();
    expect(describeStart({ x: 12.34, y: 45.6, radius_m: 10, node: 7 })).toBe(
      "Start set at E 12.3  N 45.6 ± 10 m (node 7)",
    );
  });

  it("shows what the server said when it refused", () => {
    expect(detailText({ detail: "(500.0, 20.0) is 80.0 m off the map", field: "x" })).toBe(
      "x: (500.0, 20.0) is 80.0 m off the map",
    );
    expect(detailText({ detail: "x is 80 m off the map", field: "x" })).toBe("x is 80 m off the map");
    expect(detailText({ detail: "not found", field: null })).toBe("not found");
    expect(
      detailText({
        detail: [
          { loc: ["body", "x"], msg: "Input should be a valid number", type: "float_parsing" },
          { loc: ["body", "radius_m"], msg: "Input should be greater than 0", type: "greater_than" },
        ],
      }),
    ).toBe("x: Input should be a valid number; radius_m: Input should be greater than 0");
    expect(detailText({})).toBeNull();
  });
});

import { describe, expect, it } from "vitest";
import { confidenceColour, driveColour, residualClass, rgbCss } from "./colours";

describe("colour scales", () => {
  it("runs confidence from red through amber to green and clamps", () => {
    expect(confidenceColour(0)).toEqual([229, 72, 77]);
    expect(confidenceColour(0.5)).toEqual([240, 180, 41]);
    expect(confidenceColour(1)).toEqual([48, 196, 120]);
    expect(confidenceColour(-3)).toEqual(confidenceColour(0));
    expect(confidenceColour(7)).toEqual(confidenceColour(1));
    expect(confidenceColour(Number.NaN)).toEqual(confidenceColour(0));
    const mid = confidenceColour(0.75);
    expect(mid[1]).toBeGreaterThan(180);
    expect(mid[0]).toBeLessThan(240);
  });

  it("classes residuals by distance", () => {
    expect(residualClass(0.2)).toBe("good");
    expect(residualClass(0.5)).toBe("fair");
    expect(residualClass(1.99)).toBe("fair");
    expect(residualClass(2)).toBe("bad");
    expect(residualClass(null)).toBe("none");
    expect(residualClass(undefined)).toBe("none");
  });

  it("gives neighbouring drives different colours and cycles", () => {
    expect(driveColour(1)).not.toEqual(driveColour(2));
    expect(driveColour(1)).toEqual(driveColour(9));
    expect(rgbCss([1, 2, 3])).toBe("rgb(1, 2, 3)");
    expect(rgbCss([1, 2, 3], 0.5)).toBe("rgba(1, 2, 3, 0.5)");
  });
});

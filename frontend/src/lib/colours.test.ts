import { describe, expect, it } from "vitest";
import { driveColour, residualClass, rgbCss } from "./colours";

describe("colour scales", () => {
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

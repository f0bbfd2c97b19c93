import { describe, expect, it } from "vitest";
import { bearingDeg, formatBearing, formatMotion, formatSpeed, yawToRotation } from "./motion";

const D = Math.PI / 180;

describe("yaw to an OpenLayers rotation", () => {
  it("turns an up-pointing marker clockwise onto the yaw (counter-clockwise from east)", () => {
    expect(yawToRotation(Math.PI / 2)).toBeCloseTo(0); // north: as drawn
    expect(yawToRotation(0)).toBeCloseTo(Math.PI / 2); // east: a quarter turn clockwise
    expect(yawToRotation(Math.PI)).toBeCloseTo((3 * Math.PI) / 2); // west
    expect(yawToRotation(-Math.PI / 2)).toBeCloseTo(Math.PI); // south
    expect(yawToRotation(45 * D)).toBeCloseTo(45 * D); // north-east
  });

  it("stays in [0, 2π) for any yaw", () => {
    for (const yaw of [-10, -Math.PI, 0, 3, 2 * Math.PI, 25]) {
      const r = yawToRotation(yaw);
      expect(r).toBeGreaterThanOrEqual(0);
      expect(r).toBeLessThan(2 * Math.PI);
      // the drawn direction (clockwise from north) is the yaw's
      expect(Math.cos(Math.PI / 2 - r)).toBeCloseTo(Math.cos(yaw));
      expect(Math.sin(Math.PI / 2 - r)).toBeCloseTo(Math.sin(yaw));
    }
  });
});

describe("formatting for the control room", () => {
  it("writes the heading as a grid bearing", () => {
    expect(bearingDeg(Math.PI / 2)).toBe(0);
    expect(bearingDeg(0)).toBe(90);
    expect(bearingDeg(-Math.PI / 2)).toBe(180);
    expect(bearingDeg(Math.PI)).toBe(270);
    expect(bearingDeg(Math.PI / 2 + 0.1 * D)).toBe(0); // 359.9° rounds to 0, not 360
    expect(formatBearing(45 * D)).toBe("045° NE");
    expect(formatBearing(0)).toBe("090° E");
    expect(formatBearing(null)).toBe("—");
    expect(formatBearing(undefined)).toBe("—");
  });

  it("never says 0 m/s or stopped when the server does not know", () => {
    expect(formatSpeed(1.234)).toBe("1.2 m/s");
    expect(formatSpeed(0)).toBe("0.0 m/s");
    expect(formatSpeed(-0.01)).toBe("0.0 m/s");
    expect(formatSpeed(-0.84)).toBe("0.8 m/s reversing");
    expect(formatSpeed(null)).toBe("—");
    expect(formatSpeed(undefined)).toBe("—");
    expect(formatSpeed(Number.NaN)).toBe("—");
    expect(formatMotion(true)).toBe("moving");
    expect(formatMotion(false)).toBe("stopped");
    expect(formatMotion(null)).toBe("—");
    expect(formatMotion(undefined)).toBe("—");
  });
});

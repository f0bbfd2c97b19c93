import { describe, expect, it } from "vitest";
import { Glide, angleDelta, lerpPose } from "./interpolate";

describe("marker interpolation", () => {
  it("turns the short way round", () => {
    expect(angleDelta(3, -3)).toBeCloseTo(2 * Math.PI - 6, 9);
    expect(angleDelta(-3, 3)).toBeCloseTo(6 - 2 * Math.PI, 9);
    expect(angleDelta(0, Math.PI)).toBeCloseTo(Math.PI, 9);
    const mid = lerpPose({ x: 0, y: 0, yaw: 3.1 }, { x: 0, y: 0, yaw: -3.1 }, 1);
    expect(mid.yaw).toBeCloseTo(3.1 + (2 * Math.PI - 6.2), 9);
  });

  it("starts at the old pose, ends at the new one and clamps", () => {
    const a = { x: 0, y: 0, yaw: 0 };
    const b = { x: 10, y: -4, yaw: 1 };
    expect(lerpPose(a, b, 0)).toEqual(a);
    expect(lerpPose(a, b, 1)).toEqual(b);
    expect(lerpPose(a, b, 2)).toEqual(b);
    expect(lerpPose(a, b, -1)).toEqual(a);
    const half = lerpPose(a, b, 0.5);
    expect(half.x).toBeGreaterThan(5); // ease-out: more than half way at half time
    expect(half.x).toBeLessThan(10);
  });

  it("keeps the heading of the target when one side has none", () => {
    expect(lerpPose({ x: 0, y: 0, yaw: null }, { x: 1, y: 1, yaw: 2 }, 0.3).yaw).toBe(2);
  });

  it("retargets from where the marker is drawn, never jumping", () => {
    const g = new Glide({ x: 0, y: 0, yaw: null }, 0, 1000);
    g.retarget({ x: 10, y: 0, yaw: null }, 0);
    const drawn = g.at(500);
    g.retarget({ x: 20, y: 0, yaw: null }, 500);
    expect(g.at(500).x).toBeCloseTo(drawn.x, 9);
    expect(g.done(1499)).toBe(false);
    expect(g.done(1500)).toBe(true);
    expect(g.at(1500).x).toBe(20);
  });
});

import { describe, expect, it } from "vitest";
import { LiveState, travelHeading, withHeading, type PositionMsg } from "./liveState";

const position = (seq: number, t: number, x: number, y: number, yaw: number | null = null): PositionMsg => ({
  seq,
  vehicle_id: 1,
  vehicle: "v1",
  site_id: 1,
  t,
  node: 1,
  odometry: false,
  x,
  y,
  yaw,
  confidence: 0.9,
  matched: true,
  lost: false,
  map_version: 1,
  received_at: "2026-01-01T00:00:00+00:00",
});

describe("heading from the direction of travel", () => {
  it("looks back at least the minimum travel", () => {
    expect(travelHeading([])).toBeNull();
    expect(
      travelHeading([
        { x: 0, y: 0, t: 0 },
        { x: 1, y: 0, t: 1 },
      ]),
    ).toBeNull(); // 1 m < 2 m
    const north = [
      { x: 0, y: 0, t: 0 },
      { x: 0, y: 1, t: 1 },
      { x: 0, y: 3, t: 2 },
    ];
    expect(travelHeading(north)).toBeCloseTo(Math.PI / 2);
    const west = [
      { x: 10, y: 0, t: 0 },
      { x: 7, y: 0, t: 1 },
      { x: 6.5, y: 0, t: 2 },
    ];
    expect(travelHeading(west)).toBeCloseTo(Math.PI);
  });

  it("is kept while the vehicle stands and the estimate's own yaw wins", () => {
    const s = new LiveState();
    s.apply({ type: "position", ...position(1, 0, 0, 0) });
    const v = s.vehicles.get(1)!;
    expect(v.heading).toBeNull();
    expect(withHeading(v)).toBe(v);
    s.apply({ type: "position", ...position(2, 1, 5, 0) });
    expect(v.heading).toBeCloseTo(0);
    s.apply({ type: "position", ...position(3, 2, 5, 0) }); // stopped: still facing east
    expect(v.heading).toBeCloseTo(0);
    expect(withHeading(v).position!.yaw).toBeCloseTo(0);
    expect(v.position!.yaw).toBeNull(); // the stored estimate is not changed
    s.apply({ type: "position", ...position(4, 3, 5, 0, 1.25) });
    expect(v.heading).toBe(1.25);
    expect(withHeading(v)).toBe(v);
  });
});

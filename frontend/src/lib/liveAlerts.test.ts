import { describe, expect, it } from "vitest";
import { alertsOf, cameraObscured, LiveState, statusOf, type PositionMsg } from "./liveState";

const position = (seq: number, id: number, t: number, extra: Partial<PositionMsg> = {}): PositionMsg => ({
  seq,
  vehicle_id: id,
  vehicle: `v${id}`,
  site_id: 1,
  t,
  node: 1,
  odometry: false,
  x: 0,
  y: 0,
  yaw: null,
  confidence: 0.9,
  matched: true,
  lost: false,
  map_version: 1,
  received_at: "2026-01-01T00:00:00+00:00",
  ...extra,
});

describe("camera obscured", () => {
  it("is a status below lost and above moving, and clears with the next clean estimate", () => {
    const s = new LiveState();
    s.apply({ type: "position", ...position(1, 1, 0, { obscured: true, obscured_reason: "dust" }) });
    const v = s.vehicles.get(1)!;
    expect(statusOf(v)).toBe("camera obscured");
    expect(cameraObscured(v)).toBe(true);
    s.apply({ type: "position", ...position(2, 1, 1, { obscured: true, lost: true }) });
    expect(statusOf(v)).toBe("lost");
    s.apply({ type: "position", ...position(3, 1, 2, { obscured: false, x: 5, moving: true }) });
    expect(statusOf(v)).toBe("moving");
    s.apply({ type: "position", ...position(4, 1, 3, { x: 5, moving: false }) }); // an older server: not judged
    expect(statusOf(v)).toBe("stopped");
  });

  it("alerts on live vehicles that are lost or obscured, not on stale ones", () => {
    const s = new LiveState();
    s.apply({ type: "position", ...position(1, 1, 0, { obscured: true, obscured_reason: "water" }) });
    s.apply({ type: "position", ...position(2, 2, 0, { lost: true }) });
    s.apply({ type: "position", ...position(3, 3, 0, { obscured: true }) });
    s.apply({ type: "position", ...position(4, 4, 0) });
    s.apply({ type: "stale", vehicle_id: 3, received_at: "2026-01-01T00:00:00+00:00" });
    expect(alertsOf(s.sorted())).toEqual({ lost: ["v2"], obscured: [{ name: "v1", reason: "water" }] });
    expect(alertsOf([])).toEqual({ lost: [], obscured: [] });
  });
});

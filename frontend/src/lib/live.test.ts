import { describe, expect, it } from "vitest";
import { Backoff, backoffDelay } from "./backoff";
import { LiveState, statusOf, type PositionMsg } from "./liveState";
import { LiveSocket, type SocketLike } from "./liveSocket";

function position(
  seq: number,
  vehicle_id: number,
  t: number,
  x: number,
  extra: Partial<PositionMsg> = {},
): PositionMsg {
  return {
    seq,
    vehicle_id,
    vehicle: `v${vehicle_id}`,
    site_id: 1,
    t,
    node: 1,
    odometry: false,
    x,
    y: 0,
    yaw: 0,
    confidence: 0.8,
    matched: true,
    lost: false,
    map_version: 1,
    received_at: "2026-01-01T00:00:00+00:00",
    ...extra,
  };
}

describe("backoff", () => {
  it("grows exponentially within jitter bounds and caps", () => {
    const o = { baseMs: 100, maxMs: 1000, factor: 2 };
    expect(backoffDelay(0, 0, o)).toBe(50);
    expect(backoffDelay(0, 1, o)).toBe(100);
    expect(backoffDelay(3, 1, o)).toBe(800);
    expect(backoffDelay(10, 1, o)).toBe(1000);
    expect(backoffDelay(10, 0, o)).toBe(500);
  });

  it("resets after a good connection", () => {
    const b = new Backoff({ baseMs: 100, maxMs: 1000, factor: 2 }, () => 1);
    expect([b.next(), b.next(), b.next()]).toEqual([100, 200, 400]);
    b.reset();
    expect(b.next()).toBe(100);
  });
});

describe("LiveState", () => {
  it("takes the snapshot, then positions, then stale, and remembers the last seq", () => {
    const s = new LiveState(60);
    s.apply({
      type: "snapshot",
      seq: 5,
      stale_after_s: 10,
      vehicles: [
        { vehicle_id: 1, vehicle: "v1", site_id: 1, stale: false, position: position(5, 1, 10, 0) },
        { vehicle_id: 2, vehicle: "v2", site_id: 1, stale: true, position: null },
      ],
    });
    expect(s.lastSeq).toBe(5);
    expect(statusOf(s.vehicles.get(2)!)).toBe("stale");
    expect(statusOf(s.vehicles.get(1)!)).toBe("motion unknown"); // an older server: not said
    s.apply({ type: "position", ...position(6, 1, 11, 2, { moving: true, speed_mps: 2 }) });
    expect(statusOf(s.vehicles.get(1)!)).toBe("moving");
    s.apply({ type: "position", ...position(7, 1, 12, 2, { moving: false, speed_mps: 0 }) });
    expect(statusOf(s.vehicles.get(1)!)).toBe("stopped");
    s.apply({ type: "position", ...position(8, 1, 12.5, 2.5, { moving: null, speed_mps: null }) });
    expect(statusOf(s.vehicles.get(1)!)).toBe("motion unknown"); // never guessed from the trail
    s.apply({ type: "position", ...position(9, 1, 13, 2, { lost: true, moving: true }) });
    expect(statusOf(s.vehicles.get(1)!)).toBe("lost");
    s.apply({ type: "stale", vehicle_id: 1, received_at: "x" });
    const v1 = s.vehicles.get(1)!;
    expect(statusOf(v1)).toBe("stale");
    expect(v1.position?.x).toBe(2); // last known position kept
    expect(s.lastSeq).toBe(9);
  });

  it("resumes from the oldest last position of the vehicles that are not stale", () => {
    const s = new LiveState(60);
    expect(s.resumeSeq()).toBeNull();
    s.apply({ type: "position", ...position(11, 1, 1, 0) });
    s.apply({ type: "position", ...position(10, 2, 1, 0) }); // published by another API process, later
    s.apply({ type: "position", ...position(12, 1, 2, 0) });
    expect(s.lastSeq).toBe(12);
    expect(s.resumeSeq()).toBe(10);
    s.apply({ type: "stale", vehicle_id: 2, received_at: "x" });
    expect(s.resumeSeq()).toBe(12);
    s.apply({ type: "stale", vehicle_id: 1, received_at: "x" });
    expect(s.resumeSeq()).toBe(12); // nobody moving: the highest seq seen
  });

  it("ignores replayed positions and trims the trail to its window", () => {
    const s = new LiveState(5);
    for (let i = 1; i <= 10; i++) s.apply({ type: "position", ...position(i, 1, i, i) });
    s.apply({ type: "position", ...position(4, 1, 4, 99) });
    const v = s.vehicles.get(1)!;
    expect(v.position?.x).toBe(10);
    expect(v.trail.map((p) => p.t)).toEqual([5, 6, 7, 8, 9, 10]);
    expect(v.trail[0]).toEqual({ x: 5, y: 0, t: 5, confidence: 0.8, lost: false }); // drawn in its band
  });
});

class FakeSocket implements SocketLike {
  onopen: ((ev: unknown) => void) | null = null;
  onmessage: ((ev: { data: unknown }) => void) | null = null;
  onclose: ((ev: unknown) => void) | null = null;
  onerror: ((ev: unknown) => void) | null = null;
  closed = false;
  sent: string[] = [];
  constructor(readonly url: string) {}
  close(): void {
    this.closed = true;
  }
  send(data: string): void {
    this.sent.push(data);
  }
  receive(message: unknown): void {
    this.onmessage?.({ data: JSON.stringify(message) });
  }
}

describe("LiveSocket", () => {
  it("reconnects with growing delays and resumes from the last seq seen", () => {
    const sockets: FakeSocket[] = [];
    const timers: { fn: () => void; ms: number }[] = [];
    const state = new LiveState();
    const live = new LiveSocket({
      url: (since) => (since === null ? "/api/live" : `/api/live?since=${since}`),
      lastSeq: () => state.lastSeq,
      onMessage: (m) => state.apply(m),
      makeSocket: (url) => {
        const s = new FakeSocket(url);
        sockets.push(s);
        return s;
      },
      schedule: (fn, ms) => timers.push({ fn, ms }),
      backoff: new Backoff({ baseMs: 100, maxMs: 1000, factor: 2 }, () => 1),
    });
    live.start();
    expect(sockets[0]!.url).toBe("/api/live");
    sockets[0]!.receive({ type: "snapshot", seq: 3, stale_after_s: 10, vehicles: [] });
    sockets[0]!.receive({ type: "position", ...position(4, 1, 1, 1) });
    sockets[0]!.onclose?.({});
    expect(timers.map((t) => t.ms)).toEqual([100]);
    timers[0]!.fn();
    expect(sockets[1]!.url).toBe("/api/live?since=4");
    sockets[1]!.onclose?.({}); // refused before any snapshot: wait longer
    expect(timers.map((t) => t.ms)).toEqual([100, 200]);
    timers[1]!.fn();
    sockets[2]!.receive({ type: "snapshot", seq: 9, stale_after_s: 10, vehicles: [] });
    sockets[2]!.onclose?.({});
    expect(timers[2]!.ms).toBe(100); // a snapshot means the connection worked: back to the first delay
    live.stop();
    expect(timers.length).toBe(3);
  });

  it("sends the auth message first once open, and no token in the URL", () => {
    const sockets: FakeSocket[] = [];
    const live = new LiveSocket({
      url: () => "/api/live",
      lastSeq: () => null,
      authMessage: () => JSON.stringify({ type: "auth", token: "secret" }),
      onMessage: () => undefined,
      makeSocket: (url) => {
        const s = new FakeSocket(url);
        sockets.push(s);
        return s;
      },
    });
    live.start();
    expect(sockets[0]!.sent).toEqual([]);
    sockets[0]!.onopen?.({});
    expect(sockets[0]!.sent).toEqual(['{"type":"auth","token":"secret"}']);
    expect(sockets[0]!.url).not.toContain("secret");
    live.stop();
  });
});

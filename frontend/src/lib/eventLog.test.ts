import { describe, expect, it } from "vitest";
import { EventLog, eventsCsvUrl, KEEP_ACKNOWLEDGED, merged, type EventRow } from "./eventLog";

const event = (id: number, extra: Partial<EventRow> = {}): EventRow => ({
  id,
  site_id: 1,
  vehicle_id: 7,
  vehicle: "lhd-1",
  kind: "lost",
  detail: null,
  started_at: `2026-12-06T08:00:${String(id % 60).padStart(2, "0")}Z`,
  ended_at: null,
  x: 10,
  y: 20,
  acknowledged_by: null,
  acknowledged_at: null,
  updated_at: "2026-12-06T08:00:00Z",
  ...extra,
});

const ACK = { acknowledged_by: "ann", acknowledged_at: "2026-12-06T08:05:00.5Z", updated_at: "2026-12-06T08:05:00.5Z" };
const ALL = { vehicleId: null, kind: null };

describe("merged", () => {
  it("never undoes an end or an acknowledgement, whatever the order the states arrive in", () => {
    const ended = event(1, { ended_at: "2026-12-06T08:01:00Z", updated_at: "2026-12-06T08:01:00Z" });
    const acknowledged = event(1, ACK);
    for (const [a, b] of [
      [ended, acknowledged],
      [acknowledged, ended],
    ] as const) {
      const both = merged(merged(undefined, a), b);
      expect(both.ended_at).toBe("2026-12-06T08:01:00Z");
      expect([both.acknowledged_by, both.acknowledged_at]).toEqual(["ann", ACK.acknowledged_at]);
      expect(both.updated_at).toBe(ACK.updated_at); // compared as instants: "…00.5Z" is after "…00Z"
    }
    expect(merged(acknowledged, event(1)).acknowledged_by).toBe("ann");
  });
});

describe("EventLog", () => {
  it("alarms once for a new open event, and keeps an ended one pending until acknowledged", () => {
    const log = new EventLog();
    expect(log.apply({ ...event(1), type: "event", change: "opened" })).toBe(true);
    expect(log.apply({ ...event(1), type: "event", change: "opened" })).toBe(false); // a repeat
    expect(log.apply(event(2, { ended_at: "2026-12-06T08:01:00Z" }))).toBe(false); // ended before it was seen
    log.apply(event(1, { ended_at: "2026-12-06T08:02:00Z" }));
    expect(log.pending(1, ALL).map((e) => e.id)).toEqual([2, 1]); // newest start first, ended ones too
    log.apply(event(1, ACK));
    expect(log.pending(1, ALL).map((e) => e.id)).toEqual([2]);
    expect(log.acknowledged(1, ALL).map((e) => [e.id, e.acknowledged_by])).toEqual([[1, "ann"]]);
    expect(log.apply(event(3, ACK))).toBe(false); // a known start: set, and acknowledged by its setter
  });

  it("filters by site, vehicle and kind", () => {
    const log = new EventLog();
    log.apply(event(1));
    log.apply(event(2, { kind: "stale", vehicle_id: 8 }));
    log.apply(event(3, { site_id: 2 }));
    expect(log.pending(1, { vehicleId: 8, kind: null }).map((e) => e.id)).toEqual([2]);
    expect(log.pending(1, { vehicleId: null, kind: "lost" }).map((e) => e.id)).toEqual([1]);
    expect(log.pending(2, ALL).map((e) => e.id)).toEqual([3]);
  });

  it("takes a snapshot's unacknowledged events as the pending ones, keeping acknowledged ones known", () => {
    const log = new EventLog();
    log.apply(event(1));
    log.apply(event(2));
    log.apply(event(3, ACK));
    log.reset([event(2, { ended_at: "2026-12-06T08:03:00Z" }), event(4)]); // 1 was acknowledged meanwhile
    expect(log.pending(1, ALL).map((e) => e.id)).toEqual([4, 2]);
    expect(log.get(2)?.ended_at).toBe("2026-12-06T08:03:00Z");
    expect(log.acknowledged(1, ALL).map((e) => e.id)).toEqual([3]);
  });

  it("forgets the oldest acknowledged events beyond its keep", () => {
    const log = new EventLog();
    for (let i = 1; i <= KEEP_ACKNOWLEDGED + 5; i++) {
      log.apply(event(i, { ...ACK, acknowledged_at: new Date(Date.UTC(2026, 11, 6, 9, 0, i)).toISOString() }));
    }
    expect(log.get(5)).toBeUndefined();
    expect(log.get(6)).toBeDefined();
    expect(log.acknowledged(1, ALL, 1)[0]!.id).toBe(KEEP_ACKNOWLEDGED + 5);
  });
});

describe("eventsCsvUrl", () => {
  it("carries the site and the panel's filters", () => {
    expect(eventsCsvUrl(3, { vehicleId: null, kind: null })).toBe("/api/events.csv?site=3");
    expect(eventsCsvUrl(3, { vehicleId: 7, kind: "low_confidence" })).toBe(
      "/api/events.csv?site=3&vehicle=7&kind=low_confidence",
    );
  });
});

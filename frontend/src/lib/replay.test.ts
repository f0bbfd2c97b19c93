import { describe, expect, it } from "vitest";
import {
  formatClock,
  indexAt,
  parseClock,
  poseAt,
  rangeBefore,
  rangeText,
  ReplayClock,
  trailUntil,
  type TrackPoint,
} from "./replay";

const point = (t: number, x: number, y: number, extra: Partial<TrackPoint> = {}): TrackPoint => ({
  t,
  x,
  y,
  yaw: null,
  confidence: 0.5,
  lost: false,
  ...extra,
});
const track = [point(10, 0, 0), point(11, 10, 0), point(13, 10, 20), point(14, 10, 20)];

describe("indexAt and poseAt", () => {
  it("finds the last point at or before a time", () => {
    expect(indexAt(track, 9)).toBe(-1);
    expect(indexAt(track, 10)).toBe(0);
    expect(indexAt(track, 12.9)).toBe(1);
    expect(indexAt(track, 99)).toBe(3);
    expect(indexAt([], 1)).toBe(-1);
  });

  it("interpolates between stored positions and heads along the travel", () => {
    const p = poseAt(track, 12)!;
    expect(p.x).toBeCloseTo(10);
    expect(p.y).toBeCloseTo(10);
    expect(p.yaw).toBeCloseTo(Math.PI / 2);
    expect(p.index).toBe(1);
    expect(poseAt(track, 10.5)!.x).toBeCloseTo(5);
    expect(poseAt(track, 10.5)!.yaw).toBeCloseTo(0);
  });

  it("clamps to the ends, keeps a stored heading and has no heading when standing still", () => {
    expect(poseAt(track, 0)).toMatchObject({ x: 0, y: 0, index: 0 });
    expect(poseAt(track, 100)).toMatchObject({ x: 10, y: 20, index: 3 });
    expect(poseAt(track, 13.5)!.yaw).toBeNull();
    expect(poseAt([point(0, 0, 0, { yaw: 1 }), point(1, 5, 5)], 0.5)!.yaw).toBe(1);
    expect(poseAt([], 3)).toBeNull();
  });

  it("cuts the trail to the window before the time", () => {
    expect(trailUntil(track, 13.2, 10).map((p) => p.t)).toEqual([10, 11, 13]);
    expect(trailUntil(track, 13.2, 2.5).map((p) => p.t)).toEqual([10, 11, 13]);
    expect(trailUntil(track, 13.2, 1.5).map((p) => p.t)).toEqual([11, 13]);
    expect(trailUntil(track, 5, 10)).toEqual([]);
  });
});

describe("ReplayClock", () => {
  it("plays at its speed, stops at the end and restarts from the start", () => {
    const clock = new ReplayClock(100, 110, 2);
    expect(clock.tick(1000)).toBe(100); // paused
    clock.play();
    expect(clock.tick(1000)).toBe(102);
    clock.speed = 10;
    expect(clock.tick(500)).toBe(107);
    expect(clock.fraction).toBeCloseTo(0.7);
    expect(clock.tick(1000)).toBe(110);
    expect(clock.playing).toBe(false);
    clock.play();
    expect(clock.now).toBe(100);
    expect(clock.playing).toBe(true);
  });

  it("seeks within the range and pauses", () => {
    const clock = new ReplayClock(0, 60);
    expect(clock.seek(30)).toBe(30);
    expect(clock.seek(-5)).toBe(0);
    expect(clock.seek(99)).toBe(60);
    clock.play();
    clock.pause();
    expect(clock.tick(5000)).toBe(0);
  });

  it("does not play an empty range", () => {
    const clock = new ReplayClock(5, 5);
    clock.play();
    expect(clock.playing).toBe(false);
    expect(clock.fraction).toBe(1);
  });
});

describe("formatClock and parseClock", () => {
  it("round-trips Unix times through the local date and time", () => {
    const t = new Date(2026, 11, 1, 16, 5, 30).getTime() / 1000;
    expect(formatClock(t)).toBe("2026-12-01 16:05:30");
    expect(parseClock("2026-12-01 16:05:30", t)).toBe(t);
    expect(parseClock("16:05", t)).toBe(t - 30);
    expect(parseClock("16:05:30", t)).toBe(t);
  });

  it("writes drive clocks as elapsed drive time, reads that or seconds, and refuses the rest", () => {
    expect(formatClock(12.34)).toBe("+0:00:12.3");
    expect(parseClock("+0:00:12.3", 0)).toBeCloseTo(12.3);
    expect(parseClock("+1:56:56.4", 0)).toBeCloseTo(7016.4);
    expect(parseClock("+0:61:00", 0)).toBeNull();
    expect(parseClock(" 12.5 ", 0)).toBe(12.5);
    expect(parseClock("16:05", 100)).toBeNull(); // a time of day means nothing on a drive clock
    expect(parseClock("soon", 0)).toBeNull();
  });

  it("widens a default range to the shown resolution so it holds the latest position", () => {
    const t = new Date(2026, 11, 1, 16, 5, 30).getTime() / 1000 + 0.9;
    const [from, to] = rangeBefore(t, 5);
    expect(from).toBe("2026-12-01 16:00:30");
    expect(to).toBe("2026-12-01 16:05:31");
    expect(parseClock(to, t)! >= t).toBe(true);
    expect(rangeBefore(500.25, 5)).toEqual(["+0:03:20.2", "+0:08:20.3"]);
    expect(rangeBefore(500.2, 1)).toEqual(["+0:07:20.2", "+0:08:20.2"]);
    expect(rangeBefore(12, 5)[0]).toBe("+0:00:00.0");
  });

  it("widens any range to the shown resolution so it holds both ends", () => {
    const t = new Date(2026, 11, 1, 16, 5, 30).getTime() / 1000;
    expect(rangeText(t + 0.4, t + 10.2)).toEqual(["2026-12-01 16:05:30", "2026-12-01 16:05:41"]);
    expect(rangeText(500.25, 503.91)).toEqual(["+0:08:20.2", "+0:08:24.0"]);
    expect(rangeText(500.2, 500.2)).toEqual(["+0:08:20.2", "+0:08:20.2"]);
  });
});

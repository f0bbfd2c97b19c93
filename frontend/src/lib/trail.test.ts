import { describe, expect, it } from "vitest";
import type { TrailPoint } from "./liveState";
import { bandRuns, isJump, splitJumps, trailRuns } from "./trail";

const pt = (t: number, x: number, confidence = 0.95, lost = false): TrailPoint => ({ t, x, y: 0, confidence, lost });

describe("trail runs", () => {
  it("joins consecutive runs of different bands at their shared point", () => {
    const points = [pt(0, 0), pt(1, 1), pt(2, 2, 0.6), pt(3, 3, 0.6), pt(4, 4, 0.2), pt(5, 5)];
    const runs = trailRuns(points, false);
    expect(runs.map((r) => r.band)).toEqual(["confident", "uncertain", "doubtful", "confident"]);
    expect(runs.map((r) => r.points.map((p) => p.x))).toEqual([
      [0, 1],
      [1, 2, 3],
      [3, 4],
      [4, 5],
    ]);
  });

  it("draws lost stretches as lost and everything grey when stale", () => {
    const points = [pt(0, 0), pt(1, 1), pt(2, 2, 0.95, true), pt(3, 3, 0.95, true)];
    expect(trailRuns(points, false).map((r) => r.band)).toEqual(["confident", "lost"]);
    expect(trailRuns(points, true).map((r) => r.band)).toEqual(["stale"]);
  });

  it("cuts the line where the vehicle jumped instead of drawing through rock", () => {
    expect(isJump(pt(0, 0), pt(1, 14))).toBe(false); // 14 m in 1 s: under 5 m + 10 m/s
    expect(isJump(pt(0, 0), pt(1, 16))).toBe(true);
    expect(isJump(pt(0, 0), pt(0.1, 7))).toBe(true);
    const points = [pt(0, 0), pt(0.1, 0.5), pt(0.2, 40), pt(0.3, 40.5), pt(0.4, 41)];
    expect(splitJumps(points).map((piece) => piece.length)).toEqual([2, 3]);
    expect(trailRuns(points, false).map((r) => r.points.length)).toEqual([2, 3]);
    expect(trailRuns([pt(0, 0), pt(0.1, 50)], false)).toEqual([]); // two lone points: nothing to draw
    expect(splitJumps([])).toEqual([]);
  });

  it("keeps a single point as one run", () => {
    expect(bandRuns([pt(0, 0)], () => "confident")).toEqual([{ band: "confident", points: [pt(0, 0)] }]);
  });
});

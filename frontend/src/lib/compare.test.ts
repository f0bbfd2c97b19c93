import { describe, expect, it } from "vitest";
import { defaultPair, displacements, linksToDraw, tracksByDrive } from "./compare";

const a = { drive_id: [1, 1, 2], frame: [0, 10, 0], x_m: [0, 10, 100], y_m: [0, 0, 50] };
const b = { drive_id: [2, 1, 1, 1], frame: [0, 0, 10, 20], x_m: [103, 0, 10, 20], y_m: [54, 0, 1, 0] };

describe("map version comparison", () => {
  it("defaults to the newest version against the one before", () => {
    expect(defaultPair([3, 1, 2])).toEqual({ a: 2, b: 3 });
    expect(defaultPair([1, 1])).toBeNull();
    expect(defaultPair([])).toBeNull();
  });

  it("matches frames by drive and frame, whatever their order", () => {
    const moved = displacements(a, b);
    expect(moved.map((d) => [d.driveId, d.frame, d.distance])).toEqual([
      [1, 0, 0],
      [1, 10, 1],
      [2, 0, 5],
    ]);
    expect(moved[2]!.a).toEqual([100, 50]);
    expect(moved[2]!.b).toEqual([103, 54]);
  });

  it("draws links only for frames that moved, the largest first when thinned", () => {
    const moved = displacements(a, b);
    expect(linksToDraw(moved, 0.5, 10).map((d) => d.distance)).toEqual([1, 5]);
    expect(linksToDraw(moved, 0.5, 1).map((d) => d.distance)).toEqual([5]);
  });

  it("splits poses into one track per drive", () => {
    const tracks = tracksByDrive(b);
    expect([...tracks.keys()]).toEqual([2, 1]);
    expect(tracks.get(1)).toEqual([
      [0, 0],
      [10, 1],
      [20, 0],
    ]);
  });
});

import { describe, expect, it } from "vitest";
import { arrowEnd, filterByDrive, joinResiduals, sortRows } from "./residuals";

const groundings = [
  { id: 1, drive_id: 1, drive: "east", frame: 10, x_m: 1, y_m: 2 },
  { id: 2, drive_id: 1, drive: "east", frame: 40, x_m: 3, y_m: 4 },
  { id: 3, drive_id: 2, drive: "west", frame: 5, x_m: 5, y_m: 6 },
  { id: 4, drive_id: 2, drive: "west", frame: 9, x_m: 7, y_m: 8 },
];
const residuals = [
  { drive: "east", frame: 10, dx_m: -0.3, dy_m: 0.4, distance_m: 0.5 },
  { drive: "east", frame: 40, dx_m: 2.0, dy_m: 0.0, distance_m: 2.0 },
  { drive: "west", frame: 5, dx_m: 0.1, dy_m: -0.1, distance_m: 0.14 },
];

describe("residual table", () => {
  const rows = joinResiduals(groundings, residuals);

  it("joins residuals on drive and frame, leaving new groundings without", () => {
    expect(rows.map((r) => r.distance)).toEqual([0.5, 2.0, 0.14, null]);
    expect(rows[0]).toMatchObject({ id: 1, driveId: 1, dx: -0.3, dy: 0.4 });
  });

  it("sorts by distance both ways with unbuilt rows last", () => {
    expect(sortRows(rows, "distance", "asc").map((r) => r.id)).toEqual([3, 1, 2, 4]);
    expect(sortRows(rows, "distance", "desc").map((r) => r.id)).toEqual([2, 1, 3, 4]);
  });

  it("sorts dx by magnitude and drive by name then frame", () => {
    expect(sortRows(rows, "dx", "asc").map((r) => r.id)).toEqual([3, 1, 2, 4]);
    expect(sortRows(rows, "drive", "desc").map((r) => r.id)).toEqual([3, 4, 1, 2]);
    expect(sortRows(rows, "frame", "asc").map((r) => r.id)).toEqual([3, 4, 1, 2]);
  });

  it("does not change its input", () => {
    const before = rows.map((r) => r.id);
    sortRows(rows, "distance", "desc");
    expect(rows.map((r) => r.id)).toEqual(before);
  });

  it("carries station and enabled, defaulting to none and enabled", () => {
    const first = { id: 1, drive_id: 1, drive: "east", frame: 10, x_m: 1, y_m: 2 };
    const marked = joinResiduals([{ ...first, station: "STN-1", enabled: false }], residuals);
    expect(marked[0]).toMatchObject({ station: "STN-1", enabled: false });
    expect(rows[1]).toMatchObject({ station: null, enabled: true });
  });

  it("filters by drive", () => {
    expect(filterByDrive(rows, 2).map((r) => r.id)).toEqual([3, 4]);
    expect(filterByDrive(rows, null)).toHaveLength(4);
  });
});

describe("arrowEnd", () => {
  it("ends at the pose unexaggerated and factor times as far otherwise", () => {
    expect(arrowEnd([10, 20], [11, 18], 1)).toEqual([11, 18]);
    expect(arrowEnd([10, 20], [11, 18], 10)).toEqual([20, 0]);
    expect(arrowEnd([10, 20], [10, 20], 50)).toEqual([10, 20]);
  });
});

import { describe, expect, it } from "vitest";
import { LocalOrigin, formatGrid } from "./localOrigin";

describe("LocalOrigin", () => {
  it("puts the origin at the rounded centre of the extent", () => {
    const o = LocalOrigin.ofExtent([13652.5, 56899.4, 13694.6, 56936.0]);
    expect([o.x0, o.y0]).toEqual([13700, 56900]);
  });

  it("round-trips world -> local -> world exactly for metre-scale mine grids", () => {
    const o = LocalOrigin.ofExtent([500000, 7000000, 502000, 7003000]);
    const [lx, ly] = o.toLocal(501234.567, 7001987.654);
    expect(Math.abs(lx)).toBeLessThan(2000);
    expect(Math.abs(ly)).toBeLessThan(2000);
    const [x, y] = o.toWorld(lx, ly);
    expect(x).toBeCloseTo(501234.567, 9);
    expect(y).toBeCloseTo(7001987.654, 9);
  });

  it("keeps float32 precision near the origin where world coordinates would lose it", () => {
    const o = new LocalOrigin(7000000, 7000000);
    const world = 7000000.123;
    expect(Math.abs(Math.fround(world) - world)).toBeGreaterThan(0.05);
    const [local] = o.toLocal(world, 0);
    expect(Math.abs(Math.fround(local) - local)).toBeLessThan(1e-6);
  });

  it("shifts nested GeoJSON coordinates and keeps extra dimensions", () => {
    const o = new LocalOrigin(100, 200);
    expect(
      o.shiftCoordinates([
        [101, 202, 5],
        [99, 198],
      ]),
    ).toEqual([
      [1, 2, 5],
      [-1, -2],
    ]);
    expect(o.localExtent([100, 200, 110, 230])).toEqual([0, 0, 10, 30]);
  });

  it("formats a grid readout", () => {
    expect(formatGrid(13702.104, 56911.4)).toBe("E 13702.10  N 56911.40");
  });
});

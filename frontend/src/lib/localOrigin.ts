// Mine-grid coordinates (easting/northing in metres, often 10^4..10^6) lose precision as 32-bit floats on the
// GPU. Every geometry is shifted to a local origin (the plan's centre, rounded) before it reaches the map; the
// readout adds the origin back.

export type Extent = [number, number, number, number];

export class LocalOrigin {
  constructor(
    readonly x0: number,
    readonly y0: number,
  ) {}

  /** An origin at the centre of ``extent`` rounded to ``step`` metres (so local numbers stay readable). */
  static ofExtent(extent: readonly number[], step = 100): LocalOrigin {
    const [minX, minY, maxX, maxY] = extent;
    if (minX === undefined || minY === undefined || maxX === undefined || maxY === undefined) {
      return new LocalOrigin(0, 0);
    }
    const round = (v: number): number => Math.round(v / step) * step;
    return new LocalOrigin(round((minX + maxX) / 2), round((minY + maxY) / 2));
  }

  toLocal(x: number, y: number): [number, number] {
    return [x - this.x0, y - this.y0];
  }

  toWorld(x: number, y: number): [number, number] {
    return [x + this.x0, y + this.y0];
  }

  localExtent(extent: readonly number[]): Extent {
    const [a, b] = this.toLocal(extent[0] ?? 0, extent[1] ?? 0);
    const [c, d] = this.toLocal(extent[2] ?? 0, extent[3] ?? 0);
    return [a, b, c, d];
  }

  /** Shift every [x, y] of a GeoJSON-style nested coordinate array; returns a new array. */
  shiftCoordinates(coordinates: unknown): unknown {
    if (Array.isArray(coordinates) && typeof coordinates[0] === "number" && typeof coordinates[1] === "number") {
      return [coordinates[0] - this.x0, coordinates[1] - this.y0, ...(coordinates.slice(2) as unknown[])];
    }
    if (Array.isArray(coordinates)) return coordinates.map((c) => this.shiftCoordinates(c));
    return coordinates;
  }
}

/** "13 702.10 E  56 911.40 N" style readout of a mine-grid point. */
export function formatGrid(x: number, y: number, digits = 2): string {
  return `E ${x.toFixed(digits)}  N ${y.toFixed(digits)}`;
}

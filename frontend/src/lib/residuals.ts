// Groundings joined with the residuals of the latest build, and their sorting for the table.

export interface GroundingRow {
  id: number;
  driveId: number;
  drive: string;
  frame: number;
  x: number;
  y: number;
  dx: number | null;
  dy: number | null;
  distance: number | null;
  station: string | null;
  /** Whether map builds use the grounding. */
  enabled: boolean;
}

export type SortKey = "drive" | "frame" | "dx" | "dy" | "distance";
export type SortDir = "asc" | "desc";

interface GroundingLike {
  id: number;
  drive_id: number;
  drive: string;
  frame: number;
  x_m: number;
  y_m: number;
  station?: string | null;
  enabled?: boolean;
}

interface ResidualLike {
  drive: string;
  frame: number;
  dx_m: number;
  dy_m: number;
  distance_m: number;
}

export function joinResiduals(groundings: GroundingLike[], residuals: ResidualLike[]): GroundingRow[] {
  const byKey = new Map(residuals.map((r) => [`${r.drive}#${r.frame}`, r]));
  return groundings.map((g) => {
    const r = byKey.get(`${g.drive}#${g.frame}`);
    return {
      id: g.id,
      driveId: g.drive_id,
      drive: g.drive,
      frame: g.frame,
      x: g.x_m,
      y: g.y_m,
      dx: r ? r.dx_m : null,
      dy: r ? r.dy_m : null,
      distance: r ? r.distance_m : null,
      station: g.station ?? null,
      enabled: g.enabled ?? true,
    };
  });
}

/**
 * Rows sorted by ``key``; rows without a residual always come last; ties keep drive then frame order.
 * dx and dy sort by magnitude (the sign says the direction, the size says how bad).
 */
export function sortRows(rows: GroundingRow[], key: SortKey, dir: SortDir): GroundingRow[] {
  const sign = dir === "asc" ? 1 : -1;
  const value = (r: GroundingRow): number | string | null => {
    switch (key) {
      case "drive":
        return r.drive;
      case "frame":
        return r.frame;
      case "dx":
        return r.dx === null ? null : Math.abs(r.dx);
      case "dy":
        return r.dy === null ? null : Math.abs(r.dy);
      case "distance":
        return r.distance;
    }
  };
  const tie = (a: GroundingRow, b: GroundingRow): number => a.drive.localeCompare(b.drive) || a.frame - b.frame;
  return [...rows].sort((a, b) => {
    const va = value(a);
    const vb = value(b);
    if (va === null && vb === null) return tie(a, b);
    if (va === null) return 1;
    if (vb === null) return -1;
    const c = typeof va === "string" ? va.localeCompare(vb as string) : va - (vb as number);
    return c !== 0 ? sign * c : tie(a, b);
  });
}

/** Rows of one drive (by id), or all rows when ``driveId`` is null. */
export function filterByDrive(rows: GroundingRow[], driveId: number | null): GroundingRow[] {
  return driveId === null ? rows : rows.filter((r) => r.driveId === driveId);
}

/** The exaggeration factors offered for the residual arrows on the plan. */
export const EXAGGERATIONS = [1, 2, 5, 10, 20, 50] as const;

/**
 * Where a residual arrow from the surveyed point ``at`` towards the keyframe's optimised ``pose`` ends when the
 * residual is drawn ``factor`` times its length (same units as the points; ``factor`` 1 ends at the pose).
 */
export function arrowEnd(at: readonly number[], pose: readonly number[], factor: number): [number, number] {
  return [at[0]! + factor * (pose[0]! - at[0]!), at[1]! + factor * (pose[1]! - at[1]!)];
}

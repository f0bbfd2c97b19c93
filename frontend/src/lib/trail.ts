// A vehicle's trail as drawn: the continuous positions (oldest first) cut where the vehicle jumped (a
// relocation or a newly set start: no line across rock) and split into runs of one confidence band.
import { confidenceBand, type ConfidenceBand } from "./confidence";
import type { TrailPoint } from "./liveState";

/** Two consecutive positions further apart than this plus ``JUMP_SPEED_MPS`` times their time step are a jump. */
export const JUMP_SLACK_M = 5;
/** Faster than any vehicle underground, metres per second. */
export const JUMP_SPEED_MPS = 10;

/** Whether the vehicle could not have driven from ``a`` to ``b`` in the time between them. */
export function isJump(a: TrailPoint, b: TrailPoint): boolean {
  const dt = Math.max(0, b.t - a.t);
  return Math.hypot(b.x - a.x, b.y - a.y) > JUMP_SLACK_M + JUMP_SPEED_MPS * dt;
}

/** The trail cut at every jump into pieces of consecutive points (each non-empty). */
export function splitJumps(trail: readonly TrailPoint[]): TrailPoint[][] {
  const pieces: TrailPoint[][] = [];
  let piece: TrailPoint[] = [];
  for (const p of trail) {
    const last = piece[piece.length - 1];
    if (last && isJump(last, p)) {
      pieces.push(piece);
      piece = [];
    }
    piece.push(p);
  }
  if (piece.length > 0) pieces.push(piece);
  return pieces;
}

/** A stretch of a trail in one band; consecutive runs share their joining point so the line is unbroken. */
export interface BandRun<P> {
  band: ConfidenceBand;
  points: P[];
}

/**
 * Split points (oldest first) into runs of one band each. The segment into a point takes that point's band;
 * each run after the first starts at the previous run's last point. A single point makes one run of one point.
 */
export function bandRuns<P>(points: readonly P[], bandOf: (p: P) => ConfidenceBand): BandRun<P>[] {
  const runs: BandRun<P>[] = [];
  for (const p of points) {
    const band = bandOf(p);
    const current = runs[runs.length - 1];
    if (current === undefined) runs.push({ band, points: [p] });
    else if (band === current.band) current.points.push(p);
    else runs.push({ band, points: [current.points[current.points.length - 1]!, p] });
  }
  return runs;
}

/** The runs to draw (two points or more each): pieces between jumps, split by band; all grey when stale. */
export function trailRuns(trail: readonly TrailPoint[], stale: boolean): BandRun<TrailPoint>[] {
  const bandOf = (p: TrailPoint) => confidenceBand(p.confidence, p.lost, stale);
  return splitJumps(trail)
    .flatMap((piece) => bandRuns(piece, bandOf))
    .filter((run) => run.points.length >= 2);
}

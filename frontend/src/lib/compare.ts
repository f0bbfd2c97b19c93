// Two map versions side by side: which pair to compare by default, and how far each frame moved from version A
// to version B (the frames both versions hold), for the compare overlay.

export interface PoseArrays {
  drive_id: number[];
  frame: number[];
  x_m: number[];
  y_m: number[];
}

export interface Displacement {
  driveId: number;
  frame: number;
  /** Position in version A, mine grid metres. */
  a: [number, number];
  /** Position in version B, mine grid metres. */
  b: [number, number];
  /** Distance between them, metres. */
  distance: number;
}

/** The default pair: the newest version as B against the one before it as A (null with fewer than two). */
export function defaultPair(versions: number[]): { a: number; b: number } | null {
  const sorted = [...new Set(versions)].sort((p, q) => p - q);
  if (sorted.length < 2) return null;
  return { a: sorted[sorted.length - 2]!, b: sorted[sorted.length - 1]! };
}

/** Every frame present in both versions with its displacement, in A's order. */
export function displacements(a: PoseArrays, b: PoseArrays): Displacement[] {
  const inB = new Map<string, number>();
  b.frame.forEach((f, i) => inB.set(`${b.drive_id[i]}#${f}`, i));
  const out: Displacement[] = [];
  a.frame.forEach((f, i) => {
    const j = inB.get(`${a.drive_id[i]}#${f}`);
    if (j === undefined) return;
    const pa: [number, number] = [a.x_m[i]!, a.y_m[i]!];
    const pb: [number, number] = [b.x_m[j]!, b.y_m[j]!];
    out.push({ driveId: a.drive_id[i]!, frame: f, a: pa, b: pb, distance: Math.hypot(pb[0] - pa[0], pb[1] - pa[1]) });
  });
  return out;
}

/**
 * Which displacements to draw as links: those of at least ``minM`` metres, thinned to at most ``maxLinks`` (the
 * largest kept), so a big map does not draw a link per frame.
 */
export function linksToDraw(moved: Displacement[], minM: number, maxLinks: number): Displacement[] {
  const big = moved.filter((d) => d.distance >= minM);
  if (big.length <= maxLinks) return big;
  return [...big].sort((p, q) => q.distance - p.distance).slice(0, maxLinks);
}

/** Polylines per drive of a version's poses, in pose order (the frames as stored). */
export function tracksByDrive(poses: PoseArrays): Map<number, [number, number][]> {
  const tracks = new Map<number, [number, number][]>();
  poses.frame.forEach((_, i) => {
    const d = poses.drive_id[i]!;
    const list = tracks.get(d) ?? [];
    list.push([poses.x_m[i]!, poses.y_m[i]!]);
    tracks.set(d, list);
  });
  return tracks;
}

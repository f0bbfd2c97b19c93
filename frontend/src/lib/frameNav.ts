// Moving through a drive's frames in the grounding workstation: any frame can be selected (slider, "go to
// frame"), the strip shows every ``stride``-th frame (the keyframes) a page at a time, the arrows step from
// keyframe to keyframe and the strip's page follows the selected frame.

/** The frames of a drive of ``count`` frames the strip shows: 0, stride, 2 stride, ... */
export function keyframesOf(count: number, stride: number): number[] {
  return Array.from({ length: Math.max(0, Math.ceil(count / stride)) }, (_, i) => i * stride);
}

/** Index in ``keyframes`` (ascending) of the last keyframe at or before ``frame`` (0 before the first). */
function at(keyframes: readonly number[], frame: number): number {
  let i = 0;
  while (i + 1 < keyframes.length && keyframes[i + 1]! <= frame) i += 1;
  return i;
}

/** The strip page (of ``pageSize`` keyframes) that shows ``frame``, or the keyframe just before it. */
export function pageOf(keyframes: readonly number[], frame: number, pageSize: number): number {
  return keyframes.length === 0 ? 0 : Math.floor(at(keyframes, frame) / pageSize);
}

/**
 * The keyframe ``delta`` keyframes on from ``frame`` (clamped to the first and last): forward from a frame
 * between keyframes, the next keyframe is one step on; backward, the keyframe before it is. Null without
 * keyframes; the first keyframe when nothing is selected.
 */
export function stepFrame(keyframes: readonly number[], frame: number | null, delta: number): number | null {
  if (keyframes.length === 0) return null;
  if (frame === null) return keyframes[0]!;
  const i = at(keyframes, frame);
  const between = keyframes[i]! !== frame;
  const base = between && delta < 0 ? i + 1 : i;
  return keyframes[Math.min(keyframes.length - 1, Math.max(0, base + delta))]!;
}

/**
 * The frame typed into "go to frame" of a drive of ``count`` frames, or the reason it is not one. A frame is
 * a whole number from 0 to count - 1.
 */
export function parseFrame(text: string, count: number): { frame: number } | { error: string } {
  const t = text.trim();
  if (!/^\d+$/.test(t)) return { error: `a frame is a whole number from 0 to ${count - 1}` };
  const frame = Number(t);
  if (frame >= count) return { error: `the drive has frames 0 to ${count - 1}` };
  return { frame };
}

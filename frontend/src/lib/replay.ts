// Replay of a vehicle's position history: a clock over [start, end] of frame time that plays at a speed,
// the pose at any time between two stored positions, and the vehicle-clock formatting of the range inputs.
import { EPOCH_CLOCK_S, formatDriveTime, formatTime } from "./time";

export { EPOCH_CLOCK_S };

export interface TrackPoint {
  t: number; // frame time on the vehicle's clock, seconds
  x: number;
  y: number;
  yaw: number | null;
  confidence: number;
  lost: boolean;
  obscured?: boolean | null;
}

/** Index of the last point with ``t <= time`` (-1 before the first); ``track`` sorted by ``t``. */
export function indexAt(track: readonly TrackPoint[], time: number): number {
  let lo = 0;
  let hi = track.length - 1;
  let found = -1;
  while (lo <= hi) {
    const mid = (lo + hi) >> 1;
    if (track[mid]!.t <= time) {
      found = mid;
      lo = mid + 1;
    } else hi = mid - 1;
  }
  return found;
}

/**
 * The pose at ``time``: linear between the two stored positions around it (clamped to the track's ends);
 * the heading is the stored one or, without it, the direction of travel. Null for an empty track.
 */
export function poseAt(track: readonly TrackPoint[], time: number): (TrackPoint & { index: number }) | null {
  if (track.length === 0) return null;
  const i = indexAt(track, time);
  if (i < 0) return { ...track[0]!, t: time, index: 0 };
  if (i >= track.length - 1) return { ...track[track.length - 1]!, t: time, index: track.length - 1 };
  const a = track[i]!;
  const b = track[i + 1]!;
  const u = b.t > a.t ? (time - a.t) / (b.t - a.t) : 0;
  const moved = Math.hypot(b.x - a.x, b.y - a.y) > 1e-6;
  const yaw = a.yaw ?? (moved ? Math.atan2(b.y - a.y, b.x - a.x) : null);
  return { ...a, t: time, x: a.x + (b.x - a.x) * u, y: a.y + (b.y - a.y) * u, yaw, index: i };
}

/** The points of the track up to ``time`` and not older than ``windowS`` before it (the replayed trail). */
export function trailUntil(track: readonly TrackPoint[], time: number, windowS: number): TrackPoint[] {
  const end = indexAt(track, time);
  if (end < 0) return [];
  const start = Math.max(0, indexAt(track, time - windowS));
  return track.slice(start, end + 1);
}

/** A replay clock: ``now`` runs from ``start`` to ``end`` at ``speed`` x real time while playing. */
export class ReplayClock {
  now: number;
  playing = false;

  constructor(
    readonly start: number,
    readonly end: number,
    public speed = 1,
  ) {
    this.now = start;
  }

  /** Advance by ``elapsedMs`` of wall time; stops at the end. Returns the new time. */
  tick(elapsedMs: number): number {
    if (!this.playing) return this.now;
    this.now = Math.min(this.end, this.now + (elapsedMs / 1000) * this.speed);
    if (this.now >= this.end) this.playing = false;
    return this.now;
  }

  /** Start playing (from the start again when at the end). */
  play(): void {
    if (this.now >= this.end) this.now = this.start;
    this.playing = this.end > this.start;
  }

  pause(): void {
    this.playing = false;
  }

  /** Jump to ``time`` (clamped to the range). */
  seek(time: number): number {
    this.now = Math.min(this.end, Math.max(this.start, time));
    return this.now;
  }

  /** Fraction of the range played, 0-1. */
  get fraction(): number {
    return this.end > this.start ? (this.now - this.start) / (this.end - this.start) : 1;
  }
}

/**
 * A vehicle-clock time as the replay's range inputs take it: local ``YYYY-MM-DD HH:MM:SS`` for Unix times
 * (:func:`formatTime` with the date), else elapsed drive time ``+H:MM:SS.s`` (:func:`formatDriveTime`).
 */
export function formatClock(t: number): string {
  return t < EPOCH_CLOCK_S ? formatDriveTime(t) : formatTime(new Date(t * 1000), undefined, true);
}

/**
 * The inputs' text for the ``minutes`` before ``latest``: widened to the shown resolution (whole seconds for
 * Unix times, tenths on a drive clock) so the range holds ``latest`` itself.
 */
export function rangeBefore(latest: number, minutes: number): [string, string] {
  return rangeText(latest - minutes * 60, latest);
}

/**
 * The inputs' text for ``start`` to ``end`` (vehicle clock, seconds): widened to the shown resolution (whole
 * seconds for Unix times, tenths on a drive clock) so the range holds both ends; never before 0.
 */
export function rangeText(start: number, end: number): [string, string] {
  const step = end >= EPOCH_CLOCK_S ? 1 : 0.1;
  const from = Math.max(0, Math.floor(start / step + 1e-9) * step);
  const to = Math.ceil(end / step - 1e-9) * step;
  return [formatClock(from), formatClock(to)];
}

/**
 * Parse what :func:`formatClock` writes, or a bare ``HH:MM[:SS]`` on the day of ``reference`` (a Unix
 * time), or plain seconds. Null when it is none of these.
 */
export function parseClock(text: string, reference: number): number | null {
  const s = text.trim();
  if (/^-?\d+(\.\d+)?$/.test(s)) return Number(s);
  const drive = /^\+(\d+):([0-5]\d):([0-5]\d(?:\.\d+)?)$/.exec(s);
  if (drive) return +drive[1]! * 3600 + +drive[2]! * 60 + Number(drive[3]);
  const full = /^(\d{4})-(\d{2})-(\d{2})[ T](\d{1,2}):(\d{2})(?::(\d{2}))?$/.exec(s);
  if (full) {
    const [, y, mo, d, h, mi, se] = full;
    return new Date(+y!, +mo! - 1, +d!, +h!, +mi!, +(se ?? 0)).getTime() / 1000;
  }
  const time = /^(\d{1,2}):(\d{2})(?::(\d{2}))?$/.exec(s);
  if (time && reference >= EPOCH_CLOCK_S) {
    const day = new Date(reference * 1000);
    const [, h, mi, se] = time;
    return new Date(day.getFullYear(), day.getMonth(), day.getDate(), +h!, +mi!, +(se ?? 0)).getTime() / 1000;
  }
  return null;
}

// The one way the UI writes a time: 24-hour local clock time, "HH:MM:SS", with the date in front
// ("YYYY-MM-DD HH:MM:SS") when it is not today, so a time is never ambiguous. A vehicle's frame time is either
// Unix time (live vehicles post the wall clock) or seconds since its drive started (recorded drives); the latter
// is written as elapsed drive time, "+H:MM:SS.s".

/** A vehicle clock beyond this is Unix time; below it, seconds since the drive started. */
export const EPOCH_CLOCK_S = 1e9;

const pad = (n: number, width = 2) => String(n).padStart(width, "0");

/** ``YYYY-MM-DD`` of a local date. */
export function formatDate(at: Date): string {
  return `${at.getFullYear()}-${pad(at.getMonth() + 1)}-${pad(at.getDate())}`;
}

function sameDay(a: Date, b: Date): boolean {
  return a.getFullYear() === b.getFullYear() && a.getMonth() === b.getMonth() && a.getDate() === b.getDate();
}

/**
 * ``HH:MM:SS`` (24-hour, local) of ``at`` (a Date or an ISO 8601 string from the API), with its date in front
 * unless it falls on the day of ``now``; ``withDate`` forces the date. "—" for an unreadable time.
 */
export function formatTime(at: Date | string, now: Date = new Date(), withDate = false): string {
  const d = typeof at === "string" ? new Date(at) : at;
  if (Number.isNaN(d.getTime())) return "—";
  const clock = `${pad(d.getHours())}:${pad(d.getMinutes())}:${pad(d.getSeconds())}`;
  return withDate || !sameDay(d, now) ? `${formatDate(d)} ${clock}` : clock;
}

/** Seconds since a drive started as ``+H:MM:SS.s`` (tenths, rounded). */
export function formatDriveTime(seconds: number): string {
  const tenths = Math.round(Math.max(0, seconds) * 10);
  const s = Math.floor(tenths / 10);
  return `+${Math.floor(s / 3600)}:${pad(Math.floor(s / 60) % 60)}:${pad(s % 60)}.${tenths % 10}`;
}

/** A vehicle's frame time ``t`` (seconds): :func:`formatTime` for Unix times, else :func:`formatDriveTime`. */
export function formatFrameTime(t: number, now: Date = new Date()): string {
  return t >= EPOCH_CLOCK_S ? formatTime(new Date(t * 1000), now) : formatDriveTime(t);
}

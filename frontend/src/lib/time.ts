// The one way the UI writes a time: 24-hour local clock time, "HH:MM:SS", with the date in front
// ("YYYY-MM-DD HH:MM:SS") when it is not today, so a time is never ambiguous. A vehicle's frame time is either
// Unix time (live vehicles post the wall clock) or seconds since its drive started (recorded drives); the latter
// is written as elapsed drive time, "+H:MM:SS.s". How long ago something happened (a vehicle's "last seen") is
// an age in its largest units ("12 s", "4 min", "2 h 5 min", "3 d 2 h"), its clock time beside it in this format.

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
 * A time from the API (ISO 8601) as a Date. The server's clock is UTC: a time without a zone (as some databases
 * give it back) is read as UTC, not as local time.
 */
export function serverDate(text: string): Date {
  const zoned = /(Z|[+-]\d\d:?\d\d)$/i.test(text.trim()) || !/T\d/.test(text);
  return new Date(zoned ? text : `${text}Z`);
}

/**
 * ``HH:MM:SS`` (24-hour, local) of ``at`` (a Date or an ISO 8601 string from the API), with its date in front
 * unless it falls on the day of ``now``; ``withDate`` forces the date. "—" for an unreadable time.
 */
export function formatTime(at: Date | string, now: Date = new Date(), withDate = false): string {
  const d = typeof at === "string" ? serverDate(at) : at;
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

/**
 * An age of ``seconds`` in its largest two units: "12 s", "4 min", "2 h 5 min", "3 d 2 h" (rounded down; a
 * negative age, from clocks apart, is "0 s"). "—" when unknown.
 */
export function formatAge(seconds: number | null): string {
  if (seconds === null || !Number.isFinite(seconds)) return "—";
  const s = Math.max(0, Math.floor(seconds));
  if (s < 60) return `${s} s`;
  if (s < 3600) return `${Math.floor(s / 60)} min`;
  const h = Math.floor(s / 3600);
  if (h < 24) return `${h} h ${Math.floor(s / 60) % 60} min`;
  return `${Math.floor(h / 24)} d ${h % 24} h`;
}

/** Seconds from an API time (ISO 8601, :func:`serverDate`) to ``now``; null for an unreadable time. */
export function ageOf(at: string, now: number = Date.now()): number | null {
  const ms = serverDate(at).getTime();
  return Number.isNaN(ms) ? null : (now - ms) / 1000;
}

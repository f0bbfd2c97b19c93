import { describe, expect, it } from "vitest";
import { ageOf, formatAge, formatDate, formatDriveTime, formatFrameTime, formatTime, serverDate } from "./time";

// local times, so the tests hold in any time zone
const NOW = new Date(2026, 11, 4, 17, 30, 0);

describe("formatTime", () => {
  it("writes today's times on the 24-hour clock without a date", () => {
    expect(formatTime(new Date(2026, 11, 4, 17, 7, 24), NOW)).toBe("17:07:24");
    expect(formatTime(new Date(2026, 11, 4, 0, 0, 5), NOW)).toBe("00:00:05");
  });

  it("puts the date in front of another day's time", () => {
    expect(formatTime(new Date(2026, 11, 3, 23, 59, 59), NOW)).toBe("2026-12-03 23:59:59");
    expect(formatTime(new Date(2025, 11, 4, 17, 7, 24), NOW)).toBe("2025-12-04 17:07:24");
  });

  it("reads the API's ISO strings and can be asked for the date", () => {
    const iso = new Date(2026, 11, 4, 9, 5, 0).toISOString();
    expect(formatTime(iso, NOW)).toBe("09:05:00");
    expect(formatTime(iso, NOW, true)).toBe("2026-12-04 09:05:00");
    expect(formatTime("not a time", NOW)).toBe("—");
  });
});

describe("formatDate", () => {
  it("is year-month-day with zero padding", () => {
    expect(formatDate(new Date(2026, 0, 2))).toBe("2026-01-02");
  });
});

describe("drive and frame times", () => {
  it("writes seconds since the drive started as elapsed hours, minutes, seconds and tenths", () => {
    expect(formatDriveTime(7016.4)).toBe("+1:56:56.4");
    expect(formatDriveTime(0)).toBe("+0:00:00.0");
    expect(formatDriveTime(59.96)).toBe("+0:01:00.0");
  });

  it("writes a Unix frame time as a clock time and a drive clock as elapsed time", () => {
    expect(formatFrameTime(new Date(2026, 11, 4, 17, 7, 24).getTime() / 1000, NOW)).toBe("17:07:24");
    expect(formatFrameTime(500.2, NOW)).toBe("+0:08:20.2");
  });
});

describe("ages", () => {
  it("writes an age in its largest two units, rounded down", () => {
    expect(formatAge(0)).toBe("0 s");
    expect(formatAge(12.9)).toBe("12 s");
    expect(formatAge(59.99)).toBe("59 s");
    expect(formatAge(60)).toBe("1 min");
    expect(formatAge(3599)).toBe("59 min");
    expect(formatAge(3600 + 5 * 60 + 7)).toBe("1 h 5 min");
    expect(formatAge(3 * 86400 + 2 * 3600 + 59)).toBe("3 d 2 h");
  });

  it("writes an unknown age as a dash and a negative one (clocks apart) as none", () => {
    expect(formatAge(null)).toBe("—");
    expect(formatAge(Number.NaN)).toBe("—");
    expect(formatAge(-3)).toBe("0 s");
  });

  it("measures from an API time, reading a time without a zone as UTC", () => {
    const now = Date.UTC(2026, 11, 4, 17, 30, 0);
    expect(ageOf("2026-12-04T17:29:48Z", now)).toBe(12);
    expect(ageOf("2026-12-04T17:29:48.500000+00:00", now)).toBe(11.5);
    expect(ageOf("2026-12-04T18:29:48+01:00", now)).toBe(12);
    expect(ageOf("2026-12-04T17:29:48", now)).toBe(12);
    expect(ageOf("never", now)).toBeNull();
    expect(serverDate("2026-12-04").getTime()).toBe(new Date("2026-12-04").getTime());
  });
});

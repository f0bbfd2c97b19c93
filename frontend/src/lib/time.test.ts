import { describe, expect, it } from "vitest";
import { formatDate, formatDriveTime, formatFrameTime, formatTime } from "./time";

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

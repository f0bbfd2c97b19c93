import { describe, expect, it } from "vitest";
import { dispositionFilename, MAP_FORMATS, POSITION_FORMATS, rangeQuery, shownRange } from "./exports";

// local times, so the tests hold in any time zone
const T = new Date(2026, 11, 4, 17, 30, 0).getTime() / 1000;

describe("formats", () => {
  it("offers every format of the API, GeoJSON and CSV first", () => {
    expect(Object.keys(MAP_FORMATS)).toEqual(["geojson", "csv", "kml", "dxf", "tum", "kitti", "g2o"]);
    expect(Object.keys(POSITION_FORMATS)).toEqual(["csv", "geojson", "kml", "dxf", "tum", "kitti"]);
  });
});

describe("shownRange", () => {
  it("is a loaded replay's range, widened to whole seconds", () => {
    expect(shownRange({ latestT: T + 99, replay: [T + 0.4, T + 10.2] }, 300)).toEqual([
      "2026-12-04 17:30:00",
      "2026-12-04 17:30:11",
    ]);
  });

  it("is the window before the latest position without a replay", () => {
    expect(shownRange({ latestT: T, replay: null }, 300)).toEqual(["2026-12-04 17:25:00", "2026-12-04 17:30:00"]);
    expect(shownRange({ latestT: 500.25, replay: null }, 180)).toEqual(["+0:05:20.2", "+0:08:20.3"]);
  });

  it("is the whole history without a position", () => {
    expect(shownRange({ latestT: null, replay: null }, 300)).toEqual(["", ""]);
  });
});

describe("rangeQuery", () => {
  it("reads both ends as the replay does", () => {
    expect(rangeQuery("2026-12-04 17:25:00", "17:30", T)).toEqual({ since: T - 300, until: T });
    const drive = rangeQuery("+0:05:20.2", "500.3", 0);
    expect("since" in drive && drive.since).toBeCloseTo(320.2);
    expect("until" in drive && drive.until).toBe(500.3);
  });

  it("leaves an empty end open", () => {
    expect(rangeQuery("", " ", T)).toEqual({ since: null, until: null });
    expect(rangeQuery("10", "", T)).toEqual({ since: 10, until: null });
  });

  it("explains a time it cannot read and an end before the start", () => {
    expect(rangeQuery("yesterday", "", T)).toEqual({ error: expect.stringContaining("Write times as") as string });
    expect(rangeQuery("20", "10", T)).toEqual({ error: "The end is before the start." });
  });
});

describe("dispositionFilename", () => {
  it("prefers the UTF-8 name to the ASCII fallback", () => {
    const header = `attachment; filename="mine_-map-v2.geojson"; filename*=UTF-8''mine%C3%A9-map-v2.geojson`;
    expect(dispositionFilename(header)).toBe("mine\u00e9-map-v2.geojson");
  });

  it("reads a quoted or bare name, and drops folders", () => {
    expect(dispositionFilename('attachment; filename="tiny-positions.csv"')).toBe("tiny-positions.csv");
    expect(dispositionFilename("attachment; filename=tiny.kml")).toBe("tiny.kml");
    expect(dispositionFilename('attachment; filename="../../etc/passwd"')).toBe("passwd");
  });

  it("is null without a name", () => {
    expect(dispositionFilename(null)).toBeNull();
    expect(dispositionFilename("attachment")).toBeNull();
    expect(dispositionFilename('attachment; filename=""')).toBeNull();
  });
});

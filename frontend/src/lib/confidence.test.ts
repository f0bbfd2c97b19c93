import { describe, expect, it } from "vitest";
import { BAND_COLOURS, BAND_LABELS, confidenceBand, confidencePercent, formatConfidence } from "./confidence";

describe("one confidence", () => {
  it("is a whole percentage rounded down, clamped, NaN as 0", () => {
    expect(confidencePercent(0.934)).toBe(93);
    expect(confidencePercent(0.899)).toBe(89);
    expect(confidencePercent(0.9)).toBe(90);
    expect(confidencePercent(0.29)).toBe(29); // 0.29 * 100 is 28.999... in floating point
    expect(confidencePercent(1)).toBe(100);
    expect(confidencePercent(1.2)).toBe(100);
    expect(confidencePercent(-0.1)).toBe(0);
    expect(confidencePercent(Number.NaN)).toBe(0);
    expect(formatConfidence(0.5)).toBe("50 %");
    expect(formatConfidence(null)).toBe("—");
    expect(formatConfidence(undefined)).toBe("—");
  });

  it("has bands cut where the shown percentage is cut", () => {
    expect(confidenceBand(0.95, false)).toBe("confident");
    expect(confidenceBand(0.9, false)).toBe("confident");
    expect(confidenceBand(0.8999, false)).toBe("uncertain");
    expect(confidenceBand(0.5, false)).toBe("uncertain");
    expect(confidenceBand(0.4999, false)).toBe("doubtful");
    expect(confidenceBand(Number.NaN, false)).toBe("doubtful");
    for (let c = 0; c <= 1.0001; c += 0.001) {
      const pct = confidencePercent(c);
      const band = confidenceBand(c, false);
      expect(band).toBe(pct >= 90 ? "confident" : pct >= 50 ? "uncertain" : "doubtful");
    }
  });

  it("puts lost over the confidence and stale over everything", () => {
    expect(confidenceBand(0.99, true)).toBe("lost");
    expect(confidenceBand(0.99, true, true)).toBe("stale");
    expect(confidenceBand(0.1, false, true)).toBe("stale");
  });

  it("gives every band its own colour and a legend entry", () => {
    const colours = Object.values(BAND_COLOURS).map((c) => c.join(","));
    expect(new Set(colours).size).toBe(colours.length);
    expect(BAND_LABELS.map(([band]) => band).sort()).toEqual(Object.keys(BAND_COLOURS).sort());
    expect(BAND_LABELS[0]![1]).toContain("90 %");
  });
});

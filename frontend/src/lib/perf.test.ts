import { describe, expect, it } from "vitest";
import { mark } from "./perf";

describe("perf marks", () => {
  it("keeps the latest time of each mark and counts them", () => {
    const target = {} as Window;
    mark("survey-coarse", 120, target);
    mark("survey-coarse", 340, target);
    mark("survey-detail", 500, target);
    expect(target.__driftmapPerf).toEqual({
      "survey-coarse": 340,
      "survey-coarse#count": 2,
      "survey-detail": 500,
      "survey-detail#count": 1,
    });
  });

  it("does nothing without a window", () => {
    expect(() => mark("x", 1, undefined)).not.toThrow();
  });
});

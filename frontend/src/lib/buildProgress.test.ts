import { describe, expect, it } from "vitest";
import { BUILD_STAGES, PRESETS, overallProgress, progressText, secondsLeft } from "./buildProgress";

describe("PRESETS", () => {
  it("are the server's presets, each explained in one line", () => {
    expect(PRESETS.map((p) => p.name)).toEqual(["paper", "fast"]);
    for (const p of PRESETS) expect(p.explanation).not.toContain("\n");
  });
});

describe("overallProgress", () => {
  it("never goes back when a stage restarts at 0 %", () => {
    let last = 0;
    for (const [stage] of BUILD_STAGES) {
      for (const fraction of [0, 0.5, 1]) {
        const now = overallProgress("running", stage, fraction);
        expect(now).toBeGreaterThanOrEqual(last);
        last = now;
      }
    }
    expect(last).toBeCloseTo(1);
  });

  it("counts the earlier stages' shares", () => {
    expect(overallProgress("running", "loading drives", 0)).toBe(0);
    expect(overallProgress("running", "odometry", 0.5)).toBeCloseTo(0.02 + 0.3);
    expect(overallProgress("running", "loop closure", 0)).toBeCloseTo(0.62);
  });

  it("is 1 once succeeded, 0 for an unknown stage, and clamps the fraction", () => {
    expect(overallProgress("succeeded", "", 0)).toBe(1);
    expect(overallProgress("queued", "", 0)).toBe(0);
    expect(overallProgress("running", "odometry", 7)).toBeCloseTo(0.62);
  });
});

describe("secondsLeft", () => {
  it("goes on at the pace so far", () => {
    expect(secondsLeft(0.25, 30)).toBeCloseTo(90);
    expect(secondsLeft(0.5, 10)).toBeCloseTo(10);
  });

  it("makes no guess too early or once done", () => {
    expect(secondsLeft(0.01, 30)).toBeNull();
    expect(secondsLeft(0.5, 1)).toBeNull();
    expect(secondsLeft(1, 100)).toBeNull();
  });
});

describe("progressText", () => {
  it("says the overall percentage, the stage and the time left", () => {
    expect(progressText("running", "odometry", 0.32, 95)).toBe("32% · odometry · about 1 min left");
    expect(progressText("running", "odometry", 0.01, null)).toBe("1% · odometry · estimating the time left");
  });

  it("says a queued job waits and an ended one ended", () => {
    expect(progressText("queued", "", 0, null)).toBe("queued: waiting for a worker");
    expect(progressText("succeeded", "topological map", 1, null)).toBe("succeeded");
    expect(progressText("failed", "odometry", 0.3, null)).toBe("failed 30%");
  });
});

import { describe, expect, it } from "vitest";
import { keyframesOf, pageOf, parseFrame, stepFrame } from "./frameNav";

const KEYS = keyframesOf(95, 10); // 0, 10, ..., 90

describe("keyframesOf", () => {
  it("is every stride-th frame", () => {
    expect(KEYS).toEqual([0, 10, 20, 30, 40, 50, 60, 70, 80, 90]);
    expect(keyframesOf(0, 10)).toEqual([]);
  });
});

describe("pageOf", () => {
  it("is the page of the frame's keyframe, or of the keyframe before it", () => {
    expect(pageOf(KEYS, 0, 4)).toBe(0);
    expect(pageOf(KEYS, 39, 4)).toBe(0);
    expect(pageOf(KEYS, 40, 4)).toBe(1);
    expect(pageOf(KEYS, 94, 4)).toBe(2);
    expect(pageOf([], 5, 4)).toBe(0);
  });
});

describe("stepFrame", () => {
  it("steps keyframe by keyframe, clamped at the ends", () => {
    expect(stepFrame(KEYS, 20, 1)).toBe(30);
    expect(stepFrame(KEYS, 20, -1)).toBe(10);
    expect(stepFrame(KEYS, 0, -1)).toBe(0);
    expect(stepFrame(KEYS, 90, 1)).toBe(90);
  });

  it("from a frame between keyframes goes to the keyframes either side", () => {
    expect(stepFrame(KEYS, 23, 1)).toBe(30);
    expect(stepFrame(KEYS, 23, -1)).toBe(20);
    expect(stepFrame(KEYS, 93, 1)).toBe(90);
  });

  it("starts at the first keyframe, and has nothing without keyframes", () => {
    expect(stepFrame(KEYS, null, 1)).toBe(0);
    expect(stepFrame([], 3, 1)).toBeNull();
  });
});

describe("parseFrame", () => {
  it("reads a frame of the drive", () => {
    expect(parseFrame(" 37 ", 95)).toEqual({ frame: 37 });
    expect(parseFrame("0", 95)).toEqual({ frame: 0 });
  });

  it("explains what is not one", () => {
    expect(parseFrame("95", 95)).toEqual({ error: "the drive has frames 0 to 94" });
    expect(parseFrame("-1", 95)).toEqual({ error: "a frame is a whole number from 0 to 94" });
    expect(parseFrame("3.5", 95)).toHaveProperty("error");
    expect(parseFrame("", 95)).toHaveProperty("error");
  });
});

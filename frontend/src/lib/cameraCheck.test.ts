import { describe, expect, it } from "vitest";
import {
  checkBody,
  checkLines,
  isCheckable,
  scaledGround,
  signed,
  type CameraBlock,
  type CheckLine,
  type CheckRead,
} from "./cameraCheck";
import type { GroundRead } from "./cameraSetup";

const BLOCK: CameraBlock = {
  width: 320,
  height: 240,
  ground_roi: [0, 100, 320, 140],
  k_x: 0.01,
  k_y: 0.012,
  y_c: 1.5,
  y_h: 2.0,
  forward_sign: -1,
  ground_homography: [
    [0, 0, 6],
    [-0.03, 0, 4.8],
    [0, 0.01, -0.4],
  ],
};

// a turn check of BLOCK: the travel came out backwards, the floor's rotation fits a lever of 0.52 m
const TURN: CheckRead = {
  travelled_m: -6.02,
  sign_wrong: true,
  ratio: null,
  turned_deg: 46.43,
  direction_wrong: false,
  y_c_m: 1.5,
  fitted_y_c_m: 0.5234,
  fitted_se_m: 0.031,
  turn_y_c_m: 0.49,
  camera: { ...BLOCK, y_c: 0.5234, forward_sign: 1 },
};

const SCALE: CheckRead = {
  travelled_m: 5.8,
  sign_wrong: false,
  ratio: 1.0345,
  turned_deg: null,
  direction_wrong: null,
  y_c_m: 1.5,
  fitted_y_c_m: null,
  fitted_se_m: null,
  turn_y_c_m: null,
  camera: { ...BLOCK, k_x: 0.010345, k_y: 0.012414, y_h: 2.069 },
};

/** The lines by key (a missing one fails the test), and the keys in order. */
function byKey(lines: CheckLine[]): { get: (key: CheckLine["key"]) => CheckLine; keys: string[] } {
  const get = (key: CheckLine["key"]) => {
    const found = lines.find((l) => l.key === key);
    if (!found) throw new Error(`no ${key} line`);
    return found;
  };
  return { get, keys: lines.map((l) => l.key) };
}

describe("isCheckable", () => {
  it("takes a complete block, with or without a lens and homography", () => {
    expect(isCheckable(BLOCK)).toBe(true);
    const { ground_homography: _, ...bare } = BLOCK;
    expect(isCheckable(bare)).toBe(true);
  });
  it("refuses a block missing a key or with a key that is not a number", () => {
    const { y_h: _, ...noHeight } = BLOCK;
    expect(isCheckable(noHeight)).toBe(false);
    expect(isCheckable({ ...BLOCK, k_x: NaN })).toBe(false);
    expect(isCheckable({ ...BLOCK, width: 320.5 })).toBe(false);
    expect(isCheckable({ ...BLOCK, ground_roi: [0, 0, 10] })).toBe(false);
    expect(isCheckable({ ...BLOCK, forward_sign: 0 })).toBe(false);
    expect(isCheckable(null)).toBe(false);
  });
});

describe("checkBody", () => {
  it("asks for a distance or a turn, reverse as ticked, and the page's camera when there is one", () => {
    expect(checkBody({ kind: "distance", amount: " 6.5 ", reverse: false }, null)).toEqual({
      body: { distance_m: 6.5, reverse: false },
      blocked: null,
    });
    expect(checkBody({ kind: "turn", amount: "-45", reverse: true }, BLOCK)).toEqual({
      body: { turn_deg: -45, reverse: true, camera: BLOCK },
      blocked: null,
    });
  });
  it("leaves the value to the server: a turn of 5 degrees is sent", () => {
    expect(checkBody({ kind: "turn", amount: "5", reverse: false }, null).body).toEqual({
      turn_deg: 5,
      reverse: false,
    });
  });
  it("says what is missing or not a number", () => {
    expect(checkBody({ kind: "distance", amount: "", reverse: false }, null)).toEqual({
      body: null,
      blocked: "Type the distance driven, m",
    });
    expect(checkBody({ kind: "turn", amount: "left", reverse: false }, null).blocked).toBe("The turn is not a number");
  });
});

describe("signed", () => {
  it("writes the sign, a typographic minus, and no minus for a rounded zero", () => {
    expect(signed(46.43, 1)).toBe("+46.4");
    expect(signed(-6.02, 2)).toBe("−6.02");
    expect(signed(-0.001, 1)).toBe("+0.0");
  });
});

describe("checkLines", () => {
  it("reads a turn check: the turn, forward_sign wrong, the levers and the correction", () => {
    const lines = byKey(checkLines(TURN, { turn_deg: 45, reverse: false }));
    expect(lines.keys).toEqual([
      "travel",
      "turn",
      "sign",
      "direction",
      "fitted",
      "stated-turn",
      "configured",
      "corrected",
    ]);
    expect(lines.get("travel").text).toBe("−6.02 m along the path");
    expect(lines.get("turn").text).toBe("odometry +46.4°, stated +45.0° (+ left)");
    expect(lines.get("sign")).toMatchObject({ tone: "warn" });
    expect(lines.get("sign").text).toContain("wrong");
    expect(lines.get("sign").text).toContain("forward_sign +1");
    expect(lines.get("direction")).toMatchObject({ tone: "ok" });
    expect(lines.get("fitted").text).toBe("0.52 ± 0.03 m (the floor's rotation)");
    expect(lines.get("stated-turn").text).toBe("0.49 m (odometry turns +45.0°)");
    expect(lines.get("configured").text).toBe("1.50 m");
    expect(lines.get("corrected").text).toBe("y_c 0.523 m, forward_sign +1");
  });
  it("says when the floor fits no lever and none turns through the stated angle", () => {
    const read = { ...TURN, fitted_y_c_m: null, fitted_se_m: null, turn_y_c_m: null };
    const lines = byKey(checkLines(read, { turn_deg: 45, reverse: false }));
    expect(lines.get("fitted").text).toBe("not determined by the floor's rotation");
    expect(lines.get("stated-turn").text).toBe("none within 5 m");
  });
  it("shows a mirrored ground plane as an error and no corrected camera", () => {
    const read = { ...TURN, direction_wrong: true, camera: null };
    const lines = byKey(checkLines(read, { turn_deg: 45, reverse: false }));
    expect(lines.get("direction").tone).toBe("error");
    expect(lines.get("direction").text).toContain("mirrored");
    expect(lines.keys).not.toContain("corrected");
    expect(lines.get("sign").text).toBe("wrong: the travel came out backwards");
  });
  it("reads a scale check: the ratio, forward_sign right, the scaled keys", () => {
    const lines = byKey(checkLines(SCALE, { distance_m: 6, reverse: true }));
    expect(lines.keys).toEqual(["travel", "scale", "sign", "configured", "corrected"]);
    expect(lines.get("travel").text).toBe("+5.80 m along the starting heading (driven in reverse)");
    expect(lines.get("scale").text).toContain("ratio 1.0345: measured 6.00 m, odometry 5.80 m");
    expect(lines.get("sign")).toMatchObject({ tone: "ok" });
    expect(lines.get("corrected").text).toBe("y_c 1.500 m, forward_sign −1, k_x 0.01035 m/px, k_y 0.01241 m/px");
  });
});

describe("scaledGround", () => {
  it("takes the floor scale of the corrected block and keeps the fit's ROI and residuals", () => {
    const ground: GroundRead = {
      ground_roi: BLOCK.ground_roi,
      k_x: BLOCK.k_x,
      k_y: BLOCK.k_y,
      y_h: BLOCK.y_h,
      ground_homography: BLOCK.ground_homography ?? [],
      residuals_m: [0.001, 0.002, 0.001, 0.003],
    };
    const corrected = SCALE.camera as CameraBlock;
    expect(scaledGround(ground, corrected)).toEqual({
      ...ground,
      k_x: 0.010345,
      k_y: 0.012414,
      y_h: 2.069,
    });
    const homography = [
      [0, 0, 6.2],
      [-0.031, 0, 4.96],
      [0, 0.01, -0.4],
    ];
    expect(scaledGround(ground, { ...corrected, ground_homography: homography }).ground_homography).toBe(homography);
    expect(scaledGround(ground, { ...corrected, ground_homography: null }).ground_homography).toBe(
      ground.ground_homography,
    );
  });
});

import { describe, expect, it } from "vitest";
import {
  CHARUCO_DICTIONARIES,
  NO_POINTS,
  cameraBlock,
  groundBody,
  incompleteRows,
  intrinsicsForm,
  parseLens,
  parseMetres,
  pointsReducer,
  roiFromDrag,
  toClient,
  toImagePixel,
  type GroundRead,
  type PointsState,
  type Shown,
} from "./cameraSetup";

// a 320x240 frame drawn at 640x480, 100 px from the page's left and 50 px from its top
const SHOWN: Shown = { left: 100, top: 50, width: 640, height: 480, naturalWidth: 320, naturalHeight: 240 };

describe("toImagePixel", () => {
  it("maps a click on a scaled frame back to the frame's pixels", () => {
    expect(toImagePixel(100, 50, SHOWN)).toEqual({ px: 0, py: 0 });
    expect(toImagePixel(420, 290, SHOWN)).toEqual({ px: 160, py: 120 });
    expect(toImagePixel(740, 530, SHOWN)).toEqual({ px: 320, py: 240 });
  });
  it("clamps a pointer beside the frame to its edge", () => {
    expect(toImagePixel(0, 1000, SHOWN)).toEqual({ px: 0, py: 240 });
  });
  it("is undone by toClient", () => {
    const { px, py } = toImagePixel(333, 222, SHOWN);
    const back = toClient(px, py, SHOWN);
    expect(back.x).toBeCloseTo(333, 9);
    expect(back.y).toBeCloseTo(222, 9);
  });
  it("keeps the scale of a frame shown at its natural size", () => {
    const natural = { ...SHOWN, width: 320, height: 240 };
    expect(toImagePixel(110.5, 60.25, natural)).toEqual({ px: 10.5, py: 10.25 });
  });
});

describe("roiFromDrag", () => {
  it("spans the drag in either direction with whole pixels inside the frame", () => {
    expect(roiFromDrag({ px: 10.4, py: 100.6 }, { px: 300.2, py: 230.1 }, 320, 240)).toEqual([10, 100, 291, 131]);
    expect(roiFromDrag({ px: 300.2, py: 230.1 }, { px: 10.4, py: 100.6 }, 320, 240)).toEqual([10, 100, 291, 131]);
    expect(roiFromDrag({ px: -5, py: -5 }, { px: 400, py: 400 }, 320, 240)).toEqual([0, 0, 320, 240]);
  });
  it("is null for a click without a drag", () => {
    expect(roiFromDrag({ px: 10, py: 10 }, { px: 11, py: 40 }, 320, 240)).toBeNull();
  });
});

function withPoints(n: number): PointsState {
  let state = NO_POINTS;
  for (let i = 0; i < n; i++) state = pointsReducer(state, { type: "add", px: 10 * i, py: 20 * i });
  return state;
}

describe("pointsReducer", () => {
  it("adds rows with fresh ids and empty floor positions", () => {
    const state = withPoints(3);
    expect(state.rows.map((r) => r.id)).toEqual([1, 2, 3]);
    expect(state.rows[2]).toEqual({ id: 3, px: 20, py: 40, x_m: "", y_m: "", residual_m: null });
  });
  it("edits one row's field and deletes a row without reusing its id", () => {
    let state = pointsReducer(withPoints(3), { type: "edit", id: 2, field: "x_m", value: "1.5" });
    expect(state.rows[1]?.x_m).toBe("1.5");
    expect(state.rows[0]?.x_m).toBe("");
    state = pointsReducer(state, { type: "remove", id: 2 });
    expect(state.rows.map((r) => r.id)).toEqual([1, 3]);
    state = pointsReducer(state, { type: "add", px: 1, py: 1 });
    expect(state.rows.map((r) => r.id)).toEqual([1, 3, 4]);
  });
  it("sets residuals in order, and forgets them when a point changes", () => {
    let state = pointsReducer(withPoints(2), { type: "residuals", residuals_m: [0.01, 0.02] });
    expect(state.rows.map((r) => r.residual_m)).toEqual([0.01, 0.02]);
    state = pointsReducer(state, { type: "edit", id: 1, field: "y_m", value: "2" });
    expect(state.rows.map((r) => r.residual_m)).toEqual([null, null]);
  });
  it("ignores residuals of another set of points", () => {
    const state = withPoints(2);
    expect(pointsReducer(state, { type: "residuals", residuals_m: [0.1] })).toBe(state);
  });
  it("clears", () => {
    expect(pointsReducer(withPoints(2), { type: "clear" })).toEqual(NO_POINTS);
  });
});

describe("typed metres", () => {
  it("reads numbers and refuses blanks and words", () => {
    expect(parseMetres("2.5")).toBe(2.5);
    expect(parseMetres(" -1e-1 ")).toBe(-0.1);
    expect(parseMetres("")).toBeNull();
    expect(parseMetres("abc")).toBeNull();
    expect(parseMetres("Infinity")).toBeNull();
  });
  it("numbers the incomplete rows from 1", () => {
    let state = withPoints(3);
    for (const id of [1, 2, 3]) state = pointsReducer(state, { type: "edit", id, field: "x_m", value: "1" });
    state = pointsReducer(state, { type: "edit", id: 1, field: "y_m", value: "0" });
    state = pointsReducer(state, { type: "edit", id: 3, field: "y_m", value: "x" });
    expect(incompleteRows(state.rows)).toEqual([2, 3]);
  });
});

const LENS = {
  model: "pinhole" as const,
  K: [
    [300, 0, 160],
    [0, 300, 120],
    [0, 0, 1],
  ],
  distortion: [0.1, 0, 0, 0],
};

describe("request bodies", () => {
  it("the ground route's: points in table order, pixels to a hundredth, metres as numbers", () => {
    let state = withPoints(1);
    state = pointsReducer(state, { type: "add", px: 12.3456, py: 200.001 });
    state = pointsReducer(state, { type: "edit", id: 2, field: "x_m", value: "3.25" });
    state = pointsReducer(state, { type: "edit", id: 2, field: "y_m", value: "-0.5" });
    const body = groundBody(state.rows.slice(1), 320, 240, [0, 100, 320, 140], null);
    expect(body).toEqual({
      points: [{ px: 12.35, py: 200, x_m: 3.25, y_m: -0.5 }],
      width: 320,
      height: 240,
      ground_roi: [0, 100, 320, 140],
      lens: null,
    });
    expect(groundBody([], 320, 240, null, LENS).lens).toBe(LENS);
  });
  it("the profile's camera block: fitted values, mount, and the lens only when there is one", () => {
    const ground: GroundRead = {
      ground_roi: [0, 100, 320, 140],
      k_x: 0.01,
      k_y: 0.02,
      y_h: 3,
      ground_homography: [
        [1, 0, 0],
        [0, 1, 0],
        [0, 0, 1],
      ],
      residuals_m: [0, 0, 0, 0],
    };
    expect(cameraBlock(ground, 320, 240, { y_c: 1.5, forward_sign: -1 }, null)).toEqual({
      width: 320,
      height: 240,
      ground_roi: [0, 100, 320, 140],
      k_x: 0.01,
      k_y: 0.02,
      y_c: 1.5,
      y_h: 3,
      forward_sign: -1,
      ground_homography: ground.ground_homography,
    });
    expect(cameraBlock(ground, 320, 240, { y_c: 0, forward_sign: 1 }, LENS).lens).toBe(LENS);
  });
  it("the intrinsics route's multipart form", () => {
    const files = [new File(["a"], "b1.png"), new File(["b"], "b2.png")];
    const form = intrinsicsForm(files, 9, 6, 0.025, "fisheye");
    expect(form.getAll("images").map((f) => (f as File).name)).toEqual(["b1.png", "b2.png"]);
    expect(form.get("board")).toBe("9x6");
    expect(form.get("square_m")).toBe("0.025");
    expect(form.get("model")).toBe("fisheye");
    expect(form.get("marker_m")).toBeNull();
  });
  it("a ChArUco board's markers", () => {
    const form = intrinsicsForm([], 9, 6, 0.03, "pinhole", { markerM: 0.022, dictionary: "DICT_5X5_100" });
    expect(form.get("marker_m")).toBe("0.022");
    expect(form.get("dictionary")).toBe("DICT_5X5_100");
    expect(CHARUCO_DICTIONARIES).toContain("DICT_4X4_50");
    expect(CHARUCO_DICTIONARIES).toHaveLength(16);
  });
});

describe("parseLens", () => {
  it("reads a lens block, or the lens of a whole camera block", () => {
    expect(parseLens(JSON.stringify(LENS))).toEqual(LENS);
    expect(parseLens(JSON.stringify({ width: 320, lens: LENS }))).toEqual(LENS);
  });
  it("refuses text that is not a lens", () => {
    expect(() => parseLens("{")).toThrow();
    expect(() => parseLens('{"model": "wide", "K": [], "distortion": []}')).toThrow(/pinhole or fisheye/);
    expect(() => parseLens('{"model": "pinhole", "distortion": []}')).toThrow(/"K"/);
  });
});

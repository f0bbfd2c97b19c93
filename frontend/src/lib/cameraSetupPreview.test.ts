import { describe, expect, it } from "vitest";
import type { GroundRead, Lens } from "./cameraSetup";
import { birdseyeCaption, polygonPoints, previewBlock, previewForm, type BirdsEye } from "./cameraSetupPreview";

const LENS: Lens = {
  model: "fisheye",
  K: [
    [190, 0, 318],
    [0, 190, 242],
    [0, 0, 1],
  ],
  distortion: [0.04, -0.01, 0, 0],
};
const GROUND: GroundRead = {
  ground_roi: [8, 100, 304, 136],
  k_x: 0.02,
  k_y: 0.03,
  y_h: 4.7,
  ground_homography: [
    [0, 0, 600],
    [-3, 0, 480],
    [0, 1, -40],
  ],
  residuals_m: [0, 0, 0, 0],
};

describe("previewBlock", () => {
  it("asks for nothing without a lens or a fit", () => {
    expect(previewBlock(320, 240, null, null)).toBeNull();
  });
  it("sends the lens alone before the fit", () => {
    expect(previewBlock(640, 480, LENS, null)).toEqual({ width: 640, height: 480, lens: LENS });
  });
  it("sends the fit's ROI and homography, not its scales", () => {
    expect(previewBlock(320, 240, null, GROUND)).toEqual({
      width: 320,
      height: 240,
      ground_roi: GROUND.ground_roi,
      ground_homography: GROUND.ground_homography,
    });
  });
});

describe("previewForm", () => {
  it("holds the frame under its name and the block as JSON", async () => {
    const form = previewForm(new Blob(["png"], { type: "image/png" }), "floor.png", { width: 4, height: 3 });
    const frame = form.get("frame") as File;
    expect(frame.name).toBe("floor.png");
    expect(await frame.text()).toBe("png");
    expect(JSON.parse(form.get("camera") as string)).toEqual({ width: 4, height: 3 });
  });
});

describe("drawing", () => {
  it("writes polygon points to a tenth of a pixel", () => {
    expect(
      polygonPoints([
        [1, 2],
        [3.456, 4],
      ]),
    ).toBe("1.0,2.0 3.5,4.0");
  });
  it("captions the floor in the look frame", () => {
    const view = {
      x_range_m: [0.3, 2.6],
      y_range_m: [-1.4, 1.25],
      res_m_per_px: 0.011,
    } as BirdsEye;
    expect(birdseyeCaption(view)).toBe(
      "0.30 m to 2.60 m the way the camera looks (up), 1.25 m left to 1.40 m right; 1 px = 11 mm",
    );
  });
});

// The camera set-up page's previews (POST /api/cameras/preview): the camera block in progress they are made
// of, the multipart body, and how their answers are drawn (PNG data URLs, the footprint outline, the caption).
import type { Schemas } from "../api/client";
import type { GroundRead, Lens } from "./cameraSetup";

export type Preview = Schemas["PreviewRead"];
export type BirdsEye = Schemas["BirdsEyeRead"];

/** The keys of a camera block in progress that a preview reads (formats.md): the frame size, lens and ground. */
export interface PreviewBlock {
  width: number;
  height: number;
  lens?: Lens;
  ground_roi?: number[];
  ground_homography?: number[][];
}

/**
 * The block to preview a ``width`` x ``height`` frame with: its lens and, once the ground is fitted, the fit's ROI
 * and homography. Null when there is nothing to preview: without a lens the undistorted image is the frame
 * itself, and without a fit there is no bird's-eye view.
 */
export function previewBlock(
  width: number,
  height: number,
  lens: Lens | null,
  ground: GroundRead | null,
): PreviewBlock | null {
  if (!lens && !ground) return null;
  return {
    width,
    height,
    ...(lens ? { lens } : {}),
    ...(ground ? { ground_roi: ground.ground_roi, ground_homography: ground.ground_homography } : {}),
  };
}

/** The multipart body of ``POST /api/cameras/preview``: the frame as recorded and the block as JSON text. */
export function previewForm(frame: Blob, name: string, block: PreviewBlock): FormData {
  const form = new FormData();
  form.append("frame", frame, name);
  form.append("camera", JSON.stringify(block));
  return form;
}

/** An image of the answer (base64 PNG) as a URL an ``<img>`` shows. */
export function pngUrl(base64: string): string {
  return `data:image/png;base64,${base64}`;
}

/** ``[[x, y], ...]`` pixels as the ``points`` of an SVG polygon. */
export function polygonPoints(points: number[][]): string {
  return points.map(([x, y]) => `${(x ?? 0).toFixed(1)},${(y ?? 0).toFixed(1)}`).join(" ");
}

const metres = (v: number) => `${v.toFixed(2)} m`;

/**
 * What a bird's-eye view shows, in words: the floor it covers in the camera's look frame (x along the way the
 * camera looks, up the image; y to its left) and the size of a pixel.
 */
export function birdseyeCaption(view: BirdsEye): string {
  const [xLo = 0, xHi = 0] = view.x_range_m;
  const [yLo = 0, yHi = 0] = view.y_range_m;
  const side = (y: number) => (y >= 0 ? `${metres(y)} left` : `${metres(-y)} right`);
  const mm = Math.round(view.res_m_per_px * 1000);
  return `${metres(xLo)} to ${metres(xHi)} the way the camera looks (up), ${side(yHi)} to ${side(yLo)}; 1 px = ${mm} mm`;
}

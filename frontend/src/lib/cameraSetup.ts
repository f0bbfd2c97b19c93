// The camera set-up page's pure parts: a click on the shown frame mapped back to the frame's pixels, the
// ground region from a drag, the table of floor points, and the request bodies of the camera routes.
import type { Schemas } from "../api/client";

export type Lens = Schemas["CameraLens"];
export type GroundRead = Schemas["GroundRead"];

/** Where an image is drawn on the page (``getBoundingClientRect``) and its natural size, pixels. */
export interface Shown {
  left: number;
  top: number;
  width: number;
  height: number;
  naturalWidth: number;
  naturalHeight: number;
}

/** A pointer position on the page (client pixels) as a pixel of the frame, clamped to it. */
export function toImagePixel(clientX: number, clientY: number, shown: Shown): { px: number; py: number } {
  const sx = shown.naturalWidth / shown.width;
  const sy = shown.naturalHeight / shown.height;
  const clamp = (v: number, hi: number) => Math.min(Math.max(v, 0), hi);
  return {
    px: clamp((clientX - shown.left) * sx, shown.naturalWidth),
    py: clamp((clientY - shown.top) * sy, shown.naturalHeight),
  };
}

/** A frame pixel as a point on the page (client pixels): the inverse of ``toImagePixel``. */
export function toClient(px: number, py: number, shown: Shown): { x: number; y: number } {
  return {
    x: shown.left + (px * shown.width) / shown.naturalWidth,
    y: shown.top + (py * shown.height) / shown.naturalHeight,
  };
}

export type Roi = [number, number, number, number];

/**
 * The ground region ``[x, y, w, h]`` (whole pixels inside a ``width`` x ``height`` frame) spanned by a drag from
 * one frame pixel to another, in either direction; null when it is thinner than ``minPx``.
 */
export function roiFromDrag(
  a: { px: number; py: number },
  b: { px: number; py: number },
  width: number,
  height: number,
  minPx = 4,
): Roi | null {
  const x0 = Math.max(0, Math.floor(Math.min(a.px, b.px)));
  const y0 = Math.max(0, Math.floor(Math.min(a.py, b.py)));
  const x1 = Math.min(width, Math.ceil(Math.max(a.px, b.px)));
  const y1 = Math.min(height, Math.ceil(Math.max(a.py, b.py)));
  if (x1 - x0 < minPx || y1 - y0 < minPx) return null;
  return [x0, y0, x1 - x0, y1 - y0];
}

/** One row of the points table: a clicked pixel, its typed floor position (text as typed) and residual. */
export interface PointRow {
  id: number;
  px: number;
  py: number;
  x_m: string;
  y_m: string;
  /** Metres between the measured and the fitted floor position, from the last fit; null before one. */
  residual_m: number | null;
}

export interface PointsState {
  rows: PointRow[];
  nextId: number;
}

export type PointsAction =
  | { type: "add"; px: number; py: number }
  | { type: "edit"; id: number; field: "x_m" | "y_m"; value: string }
  | { type: "remove"; id: number }
  | { type: "residuals"; residuals_m: number[] }
  | { type: "clear" };

export const NO_POINTS: PointsState = { rows: [], nextId: 1 };

/** The points table after an action; any change of a point forgets the residuals (they were of other points). */
export function pointsReducer(state: PointsState, action: PointsAction): PointsState {
  const stale = (rows: PointRow[]) => rows.map((r) => ({ ...r, residual_m: null }));
  switch (action.type) {
    case "add": {
      const row = { id: state.nextId, px: action.px, py: action.py, x_m: "", y_m: "", residual_m: null };
      return { rows: [...stale(state.rows), row], nextId: state.nextId + 1 };
    }
    case "edit":
      return {
        ...state,
        rows: stale(state.rows).map((r) => (r.id === action.id ? { ...r, [action.field]: action.value } : r)),
      };
    case "remove":
      return { ...state, rows: stale(state.rows.filter((r) => r.id !== action.id)) };
    case "residuals":
      if (action.residuals_m.length !== state.rows.length) return state;
      return { ...state, rows: state.rows.map((r, i) => ({ ...r, residual_m: action.residuals_m[i] ?? null })) };
    case "clear":
      return NO_POINTS;
  }
}

/** A typed number: finite, else null ("" and "abc" are not numbers). */
export function parseMetres(text: string): number | null {
  if (text.trim() === "") return null;
  const value = Number(text);
  return Number.isFinite(value) ? value : null;
}

/** The rows (numbered from 1, as the server numbers them) whose floor position is missing or not a number. */
export function incompleteRows(rows: PointRow[]): number[] {
  return rows.flatMap((r, i) => (parseMetres(r.x_m) === null || parseMetres(r.y_m) === null ? [i + 1] : []));
}

/** The body of ``POST /api/cameras/ground``; pixels rounded to a hundredth. */
export function groundBody(
  rows: PointRow[],
  width: number,
  height: number,
  roi: Roi | null,
  lens: Lens | null,
): Schemas["GroundRequest"] {
  const round = (v: number) => Math.round(v * 100) / 100;
  return {
    points: rows.map((r) => ({
      px: round(r.px),
      py: round(r.py),
      x_m: parseMetres(r.x_m) ?? NaN,
      y_m: parseMetres(r.y_m) ?? NaN,
    })),
    width,
    height,
    ground_roi: roi,
    lens,
  };
}

/** The mounting facts the fit does not give: measured on the vehicle. */
export interface Mount {
  /** Metres from the rear axle to the camera, along the way the camera looks. */
  y_c: number;
  /** 1 when the camera looks ahead (the floor moves down the image driving forward), -1 when it looks behind. */
  forward_sign: 1 | -1;
}

/**
 * The ``camera`` block of a profile: the frame's size, the fitted ground, the mount and the lens; without a lens
 * the ``lens`` key is left out (a drive.json block has no ``lens: null``).
 */
export function cameraBlock(
  ground: GroundRead,
  width: number,
  height: number,
  mount: Mount,
  lens: Lens | null,
): Schemas["VehicleCamera"] {
  return {
    width,
    height,
    ground_roi: ground.ground_roi,
    k_x: ground.k_x,
    k_y: ground.k_y,
    y_c: mount.y_c,
    y_h: ground.y_h,
    forward_sign: mount.forward_sign,
    ground_homography: ground.ground_homography,
    ...(lens ? { lens } : {}),
  };
}

/** Board inner corners as the server reads them: ``COLSxROWS``. */
export function boardText(cols: number, rows: number): string {
  return `${cols}x${rows}`;
}

/** The ArUco dictionaries a ChArUco board may use, as the server names them (OpenCV's ``DICT_NxN_M``). */
export const CHARUCO_DICTIONARIES: string[] = [4, 5, 6, 7].flatMap((bits) =>
  [50, 100, 250, 1000].map((count) => `DICT_${bits}X${bits}_${count}`),
);

/** A ChArUco board's markers: their side, metres, and their dictionary. */
export interface Charuco {
  markerM: number;
  dictionary: string;
}

/** The multipart body of ``POST /api/cameras/intrinsics`` for board images (a ChArUco board with ``charuco``). */
export function intrinsicsForm(
  files: File[],
  cols: number,
  rows: number,
  squareM: number,
  model: Lens["model"],
  charuco: Charuco | null = null,
): FormData {
  const form = new FormData();
  for (const f of files) form.append("images", f, f.name);
  form.append("board", boardText(cols, rows));
  form.append("square_m", String(squareM));
  form.append("model", model);
  if (charuco) {
    form.append("marker_m", String(charuco.markerM));
    form.append("dictionary", charuco.dictionary);
  }
  return form;
}

/** A pasted lens block (or a whole camera block with one), checked for its three keys; the server checks the values. */
export function parseLens(text: string): Lens {
  const value = JSON.parse(text) as Partial<Lens> & { lens?: Lens };
  const lens = value.lens ?? value; // a whole camera block, or its lens
  if (
    (lens.model !== "pinhole" && lens.model !== "fisheye") ||
    !Array.isArray(lens.K) ||
    !Array.isArray(lens.distortion)
  ) {
    throw new Error('a lens needs "model" (pinhole or fisheye), "K" (3x3) and "distortion"');
  }
  return { model: lens.model, K: lens.K, distortion: lens.distortion };
}

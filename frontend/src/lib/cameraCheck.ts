// The Cameras page's check against a stored drive, its pure parts: whether a camera block can be checked, the
// body of ``POST /api/drives/{id}/camera-check`` from the form, the answer as lines to show, and the corrected
// block read back into the page's camera (its floor scale into the fitted ground).
import type { Schemas } from "../api/client";
import { parseMetres, type GroundRead } from "./cameraSetup";

export type CameraBlock = Schemas["VehicleCamera"];
export type CheckRequest = Schemas["CameraCheckRequest"];
export type CheckRead = Schemas["CameraCheckRead"];

/** A straight drive over a measured distance (checks the floor scale), or a drive that turns (the mounting). */
export type CheckKind = "distance" | "turn";

/** The check form as typed. */
export interface CheckForm {
  kind: CheckKind;
  /** Metres driven (``distance``) or degrees turned, + left (``turn``), as typed. */
  amount: string;
  /** The drive was in reverse. */
  reverse: boolean;
}

const finite = (v: unknown): v is number => typeof v === "number" && Number.isFinite(v);
const whole = (v: unknown): v is number => finite(v) && Number.isInteger(v) && v > 0;

/**
 * Whether ``block`` is a camera block a check can take: a whole frame size, a four-number ground ROI, finite
 * ``k_x``, ``k_y`` (m/px), ``y_c``, ``y_h`` (m) and ``forward_sign`` ±1 (lens and homography are optional;
 * the server checks their values).
 */
export function isCheckable(block: unknown): block is CameraBlock {
  if (typeof block !== "object" || block === null) return false;
  const b = block as Record<string, unknown>;
  const roi = b.ground_roi;
  return (
    whole(b.width) &&
    whole(b.height) &&
    Array.isArray(roi) &&
    roi.length === 4 &&
    roi.every(finite) &&
    [b.k_x, b.k_y, b.y_c, b.y_h].every(finite) &&
    (b.forward_sign === 1 || b.forward_sign === -1)
  );
}

/**
 * The request body for the form and the camera to check (null: the drive's own, so no ``camera`` key), or why
 * there is none yet. Only that the amount is a number is checked here; the server judges its value (e.g. a turn
 * under 20 degrees) and its refusal names the field.
 */
export function checkBody(
  form: CheckForm,
  camera: CameraBlock | null,
): { body: CheckRequest; blocked: null } | { body: null; blocked: string } {
  const what = form.kind === "distance" ? "the distance driven, m" : "the turn driven, degrees (+ left)";
  if (form.amount.trim() === "") return { body: null, blocked: `Type ${what}` };
  const amount = parseMetres(form.amount);
  if (amount === null) {
    return { body: null, blocked: `${form.kind === "distance" ? "The distance" : "The turn"} is not a number` };
  }
  const body: CheckRequest =
    form.kind === "distance"
      ? { distance_m: amount, reverse: form.reverse }
      : {
          turn_deg: amount,
          reverse: form.reverse,
        };
  if (camera) body.camera = camera;
  return { body, blocked: null };
}

/** How a line reads: fine, worth a look (a setting the check corrects), or wrong in a way it cannot correct. */
export type Tone = "ok" | "warn" | "error" | null;

/** One line of the answer: a label, the figures in words, and its tone. */
export interface CheckLine {
  key: "travel" | "scale" | "turn" | "sign" | "direction" | "fitted" | "stated-turn" | "configured" | "corrected";
  label: string;
  text: string;
  tone: Tone;
}

/** ``v`` with its sign, ``+1.5`` or ``−1.5`` (a typographic minus). */
export function signed(v: number, digits: number): string {
  const text = Math.abs(v).toFixed(digits);
  return v < 0 && Number(text) !== 0 ? `−${text}` : `+${text}`;
}

const sign = (s: number) => (s === -1 ? "−1" : "+1");

/** The corrected block's settings in words (the lever, forward_sign and, from a scale check, ``k_x``). */
export function correctionText(camera: CameraBlock, scaled: boolean): string {
  const scale = scaled ? `, k_x ${camera.k_x.toFixed(5)} m/px, k_y ${camera.k_y.toFixed(5)} m/px` : "";
  return `y_c ${camera.y_c.toFixed(3)} m, forward_sign ${sign(camera.forward_sign)}${scale}`;
}

/** The answer of a check as lines to show, read against the body that was sent. */
export function checkLines(read: CheckRead, body: CheckRequest): CheckLine[] {
  const lines: CheckLine[] = [];
  const corrected = isCheckable(read.camera) ? read.camera : null;
  const along = body.distance_m != null ? "along the starting heading" : "along the path";
  const reverse = body.reverse ? " (driven in reverse)" : "";
  lines.push({
    key: "travel",
    label: "travel",
    text: `${signed(read.travelled_m, 2)} m ${along}${reverse}`,
    tone: null,
  });
  if (body.distance_m != null && read.ratio !== null) {
    lines.push({
      key: "scale",
      label: "scale",
      text:
        `ratio ${read.ratio.toFixed(4)}: measured ${body.distance_m.toFixed(2)} m, odometry ` +
        `${Math.abs(read.travelled_m).toFixed(2)} m; every floor length (k_x, k_y, y_h) times ${read.ratio.toFixed(4)}`,
      tone: null,
    });
  }
  if (body.turn_deg != null && read.turned_deg !== null) {
    lines.push({
      key: "turn",
      label: "turn",
      text: `odometry ${signed(read.turned_deg, 1)}°, stated ${signed(body.turn_deg, 1)}° (+ left)`,
      tone: null,
    });
  }
  const flipped = corrected ? ` (the corrected camera has forward_sign ${sign(corrected.forward_sign)})` : "";
  lines.push(
    read.sign_wrong
      ? { key: "sign", label: "forward_sign", text: `wrong: the travel came out backwards${flipped}`, tone: "warn" }
      : { key: "sign", label: "forward_sign", text: "right: the travel came out forwards", tone: "ok" },
  );
  if (read.direction_wrong !== null) {
    lines.push(
      read.direction_wrong
        ? {
            key: "direction",
            label: "direction",
            text:
              "odometry turned the other way: the ground plane is mirrored. Fit the ground again with floor y " +
              "measured to the camera's left; there is no corrected camera.",
            tone: "error",
          }
        : { key: "direction", label: "direction", text: "right: odometry turned the stated way", tone: "ok" },
    );
  }
  if (body.turn_deg != null) {
    lines.push({
      key: "fitted",
      label: "lever from the floor",
      text:
        read.fitted_y_c_m !== null
          ? `${read.fitted_y_c_m.toFixed(2)} ± ${(read.fitted_se_m ?? NaN).toFixed(2)} m (the floor's rotation)`
          : "not determined by the floor's rotation",
      tone: null,
    });
    lines.push({
      key: "stated-turn",
      label: "lever for the stated turn",
      text:
        read.turn_y_c_m !== null
          ? `${read.turn_y_c_m.toFixed(2)} m (odometry turns ${signed(body.turn_deg, 1)}°)`
          : "none within 5 m",
      tone: null,
    });
  }
  lines.push({ key: "configured", label: "camera's y_c", text: `${read.y_c_m.toFixed(2)} m`, tone: null });
  if (corrected) {
    lines.push({
      key: "corrected",
      label: "corrected camera",
      text: correctionText(corrected, body.distance_m != null),
      tone: null,
    });
  }
  return lines;
}

/**
 * The fitted ground with the corrected block's floor scale: ``k_x``, ``k_y`` (m/px), ``y_h`` (m) and the
 * homography (its floor side scaled); the ROI and the residuals of the fit stay.
 */
export function scaledGround(ground: GroundRead, corrected: CameraBlock): GroundRead {
  return {
    ...ground,
    k_x: corrected.k_x,
    k_y: corrected.k_y,
    y_h: corrected.y_h,
    ground_homography: corrected.ground_homography ?? ground.ground_homography,
  };
}

// Zoom and pan of an image in a fixed frame (the grounding workstation's large keyframe view): the image is
// drawn at ``scale`` times the frame's fitted size, shifted by (x, y) CSS pixels, its top-left corner the origin.

export interface ZoomView {
  scale: number;
  x: number;
  y: number;
}

export const FIT: ZoomView = { scale: 1, x: 0, y: 0 };
export const MIN_SCALE = 1;
export const MAX_SCALE = 8;

/** ``v`` with its shift kept so that the image covers its ``width`` x ``height`` frame (no empty margin). */
function clampShift(v: ZoomView, width: number, height: number): ZoomView {
  const clamp = (t: number, size: number) => Math.min(0, Math.max(size - size * v.scale, t));
  return { scale: v.scale, x: clamp(v.x, width), y: clamp(v.y, height) };
}

/**
 * ``v`` zoomed by ``factor`` about the frame pixel (px, py), which stays over the same image point; the scale
 * kept between MIN_SCALE and MAX_SCALE, the image covering the frame.
 */
export function zoomAt(v: ZoomView, factor: number, px: number, py: number, width: number, height: number): ZoomView {
  const scale = Math.min(MAX_SCALE, Math.max(MIN_SCALE, v.scale * factor));
  const k = scale / v.scale;
  return clampShift({ scale, x: px - k * (px - v.x), y: py - k * (py - v.y) }, width, height);
}

/** ``v`` panned by (dx, dy) frame pixels, the image covering the frame. */
export function panBy(v: ZoomView, dx: number, dy: number, width: number, height: number): ZoomView {
  return clampShift({ scale: v.scale, x: v.x + dx, y: v.y + dy }, width, height);
}

// Which simplification level to ask the server for: ``GET /api/sites/{id}/survey/layers?zoom=Z`` simplifies to
// half a pixel of a plan drawn 256 * 2^Z pixels across (the server's TILE_PX and MAX_ZOOM).

export const TILE_PX = 256;
export const MAX_ZOOM = 30;

/** The smallest server zoom whose tolerance is at most half a screen pixel at ``resolution`` metres/pixel. */
export function serverZoomFor(sideM: number, resolutionMPerPx: number, maxZoom = MAX_ZOOM): number {
  if (!(sideM > 0) || !(resolutionMPerPx > 0)) return 0;
  const planPx = sideM / resolutionMPerPx;
  const zoom = Math.ceil(Math.log2(planPx / TILE_PX) - 1e-9);
  return Math.min(maxZoom, Math.max(0, zoom));
}

// The plan's text (the DXF's TEXT, MTEXT and block ATTRIBs, served as Point features with ``properties.text``):
// the labels to draw, shifted to the local origin, and their size on screen, which follows the zoom like the
// drawing's own lettering (a label keeps its DXF height in metres, ``properties.height_m``), hidden when too
// small to read.

export interface SurveyLabel {
  text: string;
  /** Local-origin plane metres. */
  x: number;
  y: number;
  /** The lettering's height on the ground, metres. */
  heightM: number;
}

/** The height a plan label without its own is drawn at, metres on the ground (a typical survey annotation). */
export const LABEL_HEIGHT_M = 2.5;
/** Below this size on screen a label is left out; above the largest it stops growing. */
export const MIN_LABEL_PX = 8;
export const MAX_LABEL_PX = 22;

interface FeatureLike {
  geometry?: { type?: string; coordinates?: unknown } | null;
  properties?: { text?: unknown; height_m?: unknown } | null;
}

/** The labels of a layer's GeoJSON FeatureCollection: its Point features with a non-blank text. */
export function labelsOf(collection: unknown, x0: number, y0: number): SurveyLabel[] {
  const features = (collection as { features?: FeatureLike[] } | null)?.features ?? [];
  const out: SurveyLabel[] = [];
  for (const f of features) {
    const text = f.properties?.text;
    const at = f.geometry?.coordinates;
    if (f.geometry?.type !== "Point" || typeof text !== "string" || !Array.isArray(at)) continue;
    const [x, y] = at as number[];
    if (text.trim() === "" || !Number.isFinite(x) || !Number.isFinite(y)) continue;
    const h = f.properties?.height_m;
    const heightM = typeof h === "number" && h > 0 && Number.isFinite(h) ? h : LABEL_HEIGHT_M;
    out.push({ text: text.trim(), x: x! - x0, y: y! - y0, heightM });
  }
  return out;
}

/** The font size (CSS px) of a label at ``resolution`` metres per pixel; null when it would be unreadable. */
export function labelFontPx(resolution: number, heightM: number = LABEL_HEIGHT_M): number | null {
  if (!(resolution > 0)) return null;
  const px = heightM / resolution;
  return px < MIN_LABEL_PX ? null : Math.min(MAX_LABEL_PX, Math.round(px));
}

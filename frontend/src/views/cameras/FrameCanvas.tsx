// The chosen floor frame, large (scaled to the panel's width, never above its natural size), with the ground
// region and the clicked points drawn over it. In the region mode a drag draws the region; in the points mode a
// click adds a point. Clicks are mapped back to the frame's own pixels (toImagePixel).
import { useRef, useState, type PointerEvent } from "react";
import { roiFromDrag, toImagePixel, type PointRow, type Roi } from "../../lib/cameraSetup";

export type ClickMode = "region" | "points";

interface Props {
  url: string;
  name: string;
  mode: ClickMode;
  roi: Roi | null;
  rows: PointRow[];
  /** The frame's natural size, once it has loaded. */
  size: { width: number; height: number } | null;
  onSize: (size: { width: number; height: number }) => void;
  onRoi: (roi: Roi) => void;
  onPoint: (px: number, py: number) => void;
}

type Pixel = { px: number; py: number };
const MAX_ZOOM = 3; // a small frame is shown up to 3x its size, for precise clicks
const aspect = (size: { width: number; height: number }) => size.width / size.height;

export function FrameCanvas({ url, name, mode, roi, rows, size, onSize, onRoi, onPoint }: Props) {
  const overlay = useRef<SVGSVGElement>(null);
  const [drag, setDrag] = useState<{ from: Pixel; to: Pixel } | null>(null);

  const pixelOf = (e: PointerEvent<SVGSVGElement>): Pixel | null => {
    if (!overlay.current || !size) return null;
    const rect = overlay.current.getBoundingClientRect();
    return toImagePixel(e.clientX, e.clientY, {
      left: rect.left,
      top: rect.top,
      width: rect.width,
      height: rect.height,
      naturalWidth: size.width,
      naturalHeight: size.height,
    });
  };

  const onDown = (e: PointerEvent<SVGSVGElement>) => {
    const at = pixelOf(e);
    if (!at || e.button !== 0) return;
    if (mode === "points") {
      onPoint(at.px, at.py);
      return;
    }
    e.currentTarget.setPointerCapture(e.pointerId);
    setDrag({ from: at, to: at });
  };
  const onMove = (e: PointerEvent<SVGSVGElement>) => {
    const at = pixelOf(e);
    if (drag && at) setDrag({ ...drag, to: at });
  };
  const onUp = (e: PointerEvent<SVGSVGElement>) => {
    const at = pixelOf(e);
    if (drag && at && size) {
      const found = roiFromDrag(drag.from, at, size.width, size.height);
      if (found) onRoi(found);
    }
    setDrag(null);
  };

  const shownRoi = drag && size ? roiFromDrag(drag.from, drag.to, size.width, size.height, 1) : roi;
  const scale = size ? Math.max(size.width, size.height) / 400 : 1; // marks keep their size on screen
  return (
    <div
      className="camframe"
      data-testid="camera-frame-wrap"
      style={size ? { width: `min(100%, ${MAX_ZOOM * size.width}px, calc((100vh - 320px) * ${aspect(size)}))` } : {}}
    >
      <img
        src={url}
        alt={name}
        data-testid="camera-frame"
        onLoad={(e) => onSize({ width: e.currentTarget.naturalWidth, height: e.currentTarget.naturalHeight })}
      />
      {size && (
        <svg
          ref={overlay}
          className={`camoverlay ${mode}`}
          data-testid="camera-overlay"
          viewBox={`0 0 ${size.width} ${size.height}`}
          preserveAspectRatio="none"
          onPointerDown={onDown}
          onPointerMove={onMove}
          onPointerUp={onUp}
        >
          {shownRoi && (
            <rect
              data-testid="camera-roi"
              x={shownRoi[0]}
              y={shownRoi[1]}
              width={shownRoi[2]}
              height={shownRoi[3]}
              className="camroi"
              strokeWidth={1.5 * scale}
            />
          )}
          {rows.map((r, i) => (
            <g key={r.id} className="campoint">
              <circle cx={r.px} cy={r.py} r={4 * scale} strokeWidth={1.5 * scale} />
              <text x={r.px + 6 * scale} y={r.py - 6 * scale} fontSize={12 * scale}>
                {i + 1}
              </text>
            </g>
          ))}
        </svg>
      )}
    </div>
  );
}

// The selected frame large (at least 640 px wide) beside the plan, for reading its details while placing its
// surveyed point: the wheel zooms about the pointer, a drag pans, "Fit" goes back, Close hides the view.
import { useRef, useState, type PointerEvent, type WheelEvent } from "react";
import { FIT, panBy, zoomAt, type ZoomView } from "../lib/zoomView";
import { AuthImage } from "./AuthImage";

const WHEEL_STEP = 1.25; // zoom factor per wheel notch
const BUTTON_STEP = 1.5;

interface Props {
  driveId: number;
  driveName: string;
  frame: number;
  onClose: () => void;
}

export function FrameView({ driveId, driveName, frame, onClose }: Props) {
  const [view, setView] = useState<ZoomView>(FIT);
  const box = useRef<HTMLDivElement>(null);
  const drag = useRef<{ x: number; y: number } | null>(null);
  const size = () => [box.current?.clientWidth ?? 1, box.current?.clientHeight ?? 1] as const;

  const onWheel = (e: WheelEvent<HTMLDivElement>) => {
    const r = e.currentTarget.getBoundingClientRect();
    setView((v) =>
      zoomAt(v, e.deltaY < 0 ? WHEEL_STEP : 1 / WHEEL_STEP, e.clientX - r.left, e.clientY - r.top, ...size()),
    );
  };
  const onDown = (e: PointerEvent<HTMLDivElement>) => {
    drag.current = { x: e.clientX, y: e.clientY };
    e.currentTarget.setPointerCapture(e.pointerId);
  };
  const onMove = (e: PointerEvent<HTMLDivElement>) => {
    const from = drag.current;
    if (!from) return;
    drag.current = { x: e.clientX, y: e.clientY };
    setView((v) => panBy(v, e.clientX - from.x, e.clientY - from.y, ...size()));
  };
  const button = (factor: number) => {
    const [w, h] = size();
    setView((v) => zoomAt(v, factor, w / 2, h / 2, w, h));
  };

  return (
    <section
      className="frameview"
      data-testid="frame-view"
      data-frame={frame}
      data-scale={view.scale.toFixed(2)}
      data-shift={`${view.x.toFixed(0)},${view.y.toFixed(0)}`}
    >
      <div className="row">
        <strong>
          {driveName} frame {frame}
        </strong>
        <span className="spacer" />
        <button data-testid="frame-zoom-in" onClick={() => button(BUTTON_STEP)} title="Zoom in (wheel)">
          +
        </button>
        <button data-testid="frame-zoom-out" onClick={() => button(1 / BUTTON_STEP)} title="Zoom out (wheel)">
          −
        </button>
        <button data-testid="frame-fit" onClick={() => setView(FIT)}>
          Fit
        </button>
        <button data-testid="frame-view-close" onClick={onClose}>
          Close
        </button>
      </div>
      <div
        className="frameview-box"
        ref={box}
        onWheel={onWheel}
        onPointerDown={onDown}
        onPointerMove={onMove}
        onPointerUp={() => (drag.current = null)}
        onPointerCancel={() => (drag.current = null)}
      >
        <div style={{ transform: `translate(${view.x}px, ${view.y}px) scale(${view.scale})` }}>
          <AuthImage src={`/api/drives/${driveId}/frames/${frame}`} alt={`frame ${frame} zoomable`} />
        </div>
      </div>
      <p className="muted small">Wheel to zoom about the pointer, drag to pan; the plan stays beside it.</p>
    </section>
  );
}

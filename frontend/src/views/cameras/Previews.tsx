// The previews beside the picked frame (POST /api/cameras/preview), asked for again whenever the frame, the lens
// or the ground fit changes: "Undistorted" (once a lens is set: the ideal pinhole image of the same size and K,
// with the ground region drawn where it lies, since the region is in this image's pixels) and "Bird's-eye" (once
// the ground is fitted: the floor around the region's footprint from above, x the way the camera looks pointing
// up, the footprint outlined).
import { useEffect, useState } from "react";
import { postPreview } from "../../api/cameras";
import { ApiError } from "../../api/client";
import type { GroundRead, Lens, Roi } from "../../lib/cameraSetup";
import {
  birdseyeCaption,
  pngUrl,
  polygonPoints,
  previewBlock,
  previewForm,
  type PreviewBlock,
  type Preview,
} from "../../lib/cameraSetupPreview";
import type { Frame } from "./FramePicker";

interface Props {
  frame: Frame;
  size: { width: number; height: number };
  lens: Lens | null;
  /** The fit of the current points, or null. */
  ground: GroundRead | null;
  /** The ground region being edited (undistorted pixels), or null. */
  roi: Roi | null;
}

type Answer = { key: string; preview: Preview } | { key: string; error: string };

/** The preview of ``block`` for the frame behind ``url``, re-asked when ``key`` changes (null: none wanted). */
function usePreview(
  url: string,
  name: string,
  block: PreviewBlock | null,
): { preview: Preview | null; error: string | null } {
  const key = block ? JSON.stringify([url, block]) : null;
  const [answer, setAnswer] = useState<Answer | null>(null);
  useEffect(() => {
    if (!key) return;
    const [frameUrl, asked] = JSON.parse(key) as [string, PreviewBlock];
    let live = true;
    const ask = async () => {
      try {
        const frame = await (await fetch(frameUrl)).blob();
        const preview = await postPreview(previewForm(frame, name, asked));
        if (live) setAnswer({ key, preview });
      } catch (e) {
        if (live) setAnswer({ key, error: e instanceof ApiError ? e.message : String(e) });
      }
    };
    void ask();
    return () => {
      live = false;
    };
  }, [key, name]);
  const current = answer && answer.key === key ? answer : null;
  return {
    preview: current && "preview" in current ? current.preview : null,
    error: current && "error" in current ? current.error : null,
  };
}

export function Previews({ frame, size, lens, ground, roi }: Props) {
  const block = previewBlock(size.width, size.height, lens, ground);
  const { preview, error } = usePreview(frame.url, frame.name, block);
  if (!block) return null;
  const region = ground ? ground.ground_roi : roi;
  const view = preview?.birdseye ?? null;
  const scale = Math.max(size.width, size.height) / 320; // outlines keep their width on screen
  return (
    <div className="campreviews" data-testid="camera-previews">
      {!preview && !error && <div className="muted">Making the previews…</div>}
      {error && (
        <div className="alert" role="alert" data-testid="camera-preview-error">
          {error}
        </div>
      )}
      {preview && lens && (
        <figure data-testid="camera-preview-undistorted">
          <div className="camprevimg">
            <img src={pngUrl(preview.undistorted_png)} alt="The frame undistorted" />
            <svg viewBox={`0 0 ${preview.width} ${preview.height}`} preserveAspectRatio="none">
              {region && (
                <rect
                  className="camroi"
                  data-testid="camera-preview-roi"
                  x={region[0]}
                  y={region[1]}
                  width={region[2]}
                  height={region[3]}
                  strokeWidth={1.5 * scale}
                />
              )}
            </svg>
          </div>
          <figcaption>
            Undistorted: the pinhole image of the same size and K, the ground region where it lies
          </figcaption>
        </figure>
      )}
      {view && (
        <figure data-testid="camera-preview-birdseye">
          <div className="camprevimg">
            <img src={pngUrl(view.png)} alt="The floor from above" />
            <svg viewBox={`0 0 ${view.width} ${view.height}`} preserveAspectRatio="none">
              <polygon
                className="camroi"
                data-testid="camera-preview-footprint"
                points={polygonPoints(view.footprint_px)}
                strokeWidth={(1.5 * Math.max(view.width, view.height)) / 320}
              />
            </svg>
          </div>
          <figcaption data-testid="camera-preview-birdseye-caption">Bird's-eye: {birdseyeCaption(view)}</figcaption>
        </figure>
      )}
    </div>
  );
}

// The camera set-up page (surveyors and admins): floor frames, the ground region dragged on the frame, floor
// points clicked and measured, an optional lens, the ground fit (POST /api/cameras/ground), previews of the
// undistorted frame and of the floor from above beside the frame, a check of the camera against a stored drive
// (whose corrected camera the page can take), and the result saved as a camera profile and given to a vehicle.
// Everything stays in the page until saved.
import { useEffect, useReducer, useRef, useState } from "react";
import { apiPost } from "../../api/client";
import { scaledGround, type CameraBlock } from "../../lib/cameraCheck";
import {
  NO_POINTS,
  cameraBlock,
  groundBody,
  incompleteRows,
  pointsReducer,
  type GroundRead,
  type Lens,
  type Mount,
  type Roi,
} from "../../lib/cameraSetup";
import { useErrors } from "../useErrors";
import { DriveCheckPanel } from "./DriveCheckPanel";
import { FrameCanvas, type ClickMode } from "./FrameCanvas";
import { FramePicker, type Frame } from "./FramePicker";
import { GroundFit } from "./GroundFit";
import { LensPanel } from "./LensPanel";
import { PointsTable } from "./PointsTable";
import { Previews } from "./Previews";
import { ProfilesPanel } from "./ProfilesPanel";
import "./cameras.css";

const MIN_POINTS = 4;
type Size = { width: number; height: number };

export function CamerasView() {
  const [frames, setFrames] = useState<Frame[]>([]);
  const [current, setCurrent] = useState(0);
  const [size, setSize] = useState<Size | null>(null);
  const [mode, setMode] = useState<ClickMode>("region");
  const [roi, setRoi] = useState<Roi | null>(null);
  const [points, dispatch] = useReducer(pointsReducer, NO_POINTS);
  const [lens, setLens] = useState<Lens | null>(null);
  const [lensSize, setLensSize] = useState<Size | null>(null);
  const [mount, setMount] = useState<Mount>({ y_c: 0, forward_sign: 1 });
  const [fit, setFit] = useState<{ key: string; ground: GroundRead } | null>(null);
  // a drive's corrected camera taken while the page had no fit of its own; a fit replaces it
  const [taken, setTaken] = useState<CameraBlock | null>(null);
  const [busy, setBusy] = useState(false);
  const [fitError, run] = useErrors();

  const shown = useRef<Frame[]>([]);
  useEffect(() => {
    shown.current = frames;
  }, [frames]);
  useEffect(() => () => shown.current.forEach((f) => URL.revokeObjectURL(f.url)), []); // on leaving the page

  const frame = frames[current] ?? null;
  const body = size ? groundBody(points.rows, size.width, size.height, roi, lens) : null;
  const key = JSON.stringify(body);
  const ground = fit && fit.key === key ? fit.ground : null;
  const block =
    ground && size
      ? cameraBlock(ground, size.width, size.height, mount, lens)
      : taken
        ? { ...taken, y_c: mount.y_c, forward_sign: mount.forward_sign }
        : null;
  const missing = incompleteRows(points.rows);
  const blocked = !size
    ? "Upload a floor frame first"
    : points.rows.length < MIN_POINTS
      ? `Click ${MIN_POINTS - points.rows.length} more floor point(s)`
      : missing.length > 0
        ? `Type the floor position of point(s) ${missing.join(", ")}`
        : null;
  const lensMismatch =
    lensSize && size && (lensSize.width !== size.width || lensSize.height !== size.height)
      ? `The lens was calibrated on ${lensSize.width}x${lensSize.height} images, the frame is ${size.width}x${size.height}.`
      : null;

  const addFrames = (files: File[]) => {
    const added = files.map((f) => ({ name: f.name, url: URL.createObjectURL(f) }));
    setFrames((old) => [...old, ...added]);
    if (frames.length === 0) setMode("region");
  };
  const fitGround = () =>
    void run(async () => {
      if (!body) return;
      setBusy(true);
      try {
        const found = await apiPost("/api/cameras/ground", {}, body);
        setFit({ key, ground: found });
        setTaken(null);
        dispatch({ type: "residuals", residuals_m: found.residuals_m });
      } finally {
        setBusy(false);
      }
    });

  // a drive check's corrected camera: its lever and forward_sign into the mount, its floor scale into the fit
  // (without a fit, the whole block is taken as the page's camera)
  const takeCorrected = (corrected: CameraBlock) => {
    setMount({ y_c: corrected.y_c, forward_sign: corrected.forward_sign === -1 ? -1 : 1 });
    if (fit && ground) setFit({ key: fit.key, ground: scaledGround(ground, corrected) });
    else setTaken(corrected);
  };

  return (
    <>
      <div className="campage" data-testid="cameras-page">
        <FramePicker frames={frames} selected={current} onAdd={addFrames} onSelect={setCurrent} />
        {frame && (
          <>
            <div className="row">
              <span className="muted">Click mode:</span>
              <button
                className={mode === "region" ? "primary" : ""}
                onClick={() => setMode("region")}
                data-testid="camera-mode-region"
              >
                Ground region
              </button>
              <button
                className={mode === "points" ? "primary" : ""}
                onClick={() => setMode("points")}
                data-testid="camera-mode-points"
              >
                Points
              </button>
              <span className="hint">
                {mode === "region"
                  ? "Drag a rectangle over the floor odometry should track."
                  : "Click a floor mark, then type its floor position in the table."}
              </span>
              <span className="spacer" />
              <span className="muted" data-testid="camera-frame-size">
                {frame.name}
                {size ? ` ${size.width}x${size.height}` : ""}
                {roi ? `, region ${roi.join(", ")}` : ""}
              </span>
              {roi && <button onClick={() => setRoi(null)}>Clear region</button>}
            </div>
            <div className="camrow">
              <div className="cammain">
                <FrameCanvas
                  url={frame.url}
                  name={frame.name}
                  mode={mode}
                  roi={roi}
                  rows={points.rows}
                  size={size}
                  onSize={setSize}
                  onRoi={setRoi}
                  onPoint={(px, py) => dispatch({ type: "add", px, py })}
                />
              </div>
              {size && <Previews frame={frame} size={size} lens={lens} ground={ground} roi={roi} />}
            </div>
          </>
        )}
        <PointsTable rows={points.rows} dispatch={dispatch} />
      </div>
      <aside className="side camside">
        <LensPanel
          lens={lens}
          onLens={(l, s) => {
            setLens(l);
            setLensSize(s);
          }}
        />
        {lensMismatch && <div className="alert">{lensMismatch}</div>}
        <GroundFit
          mount={mount}
          onMount={setMount}
          blocked={blocked}
          busy={busy}
          onFit={fitGround}
          fit={ground}
          error={fitError}
        />
        <DriveCheckPanel block={block} taken={!ground && taken !== null} onUse={takeCorrected} />
        <ProfilesPanel block={block} />
      </aside>
    </>
  );
}

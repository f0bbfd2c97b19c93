// The optional lens: none (a pinhole without distortion, frames used as recorded), calibrated from chessboard
// or ChArUco images (POST /api/cameras/intrinsics: each view's RMS and the images the board was not found in),
// or a lens block pasted as JSON (e.g. from `driftmap camera intrinsics`).
import { useState } from "react";
import { postIntrinsics } from "../../api/cameras";
import type { Schemas } from "../../api/client";
import { CHARUCO_DICTIONARIES, intrinsicsForm, parseLens, type Lens } from "../../lib/cameraSetup";
import { useErrors } from "../useErrors";

type Source = "none" | "board" | "paste";

interface Props {
  lens: Lens | null;
  onLens: (lens: Lens | null, size: { width: number; height: number } | null) => void;
}

export function LensPanel({ lens, onLens }: Props) {
  const [source, setSource] = useState<Source>(lens ? "paste" : "none");
  const [files, setFiles] = useState<File[]>([]);
  const [cols, setCols] = useState(9);
  const [rows, setRows] = useState(6);
  const [square, setSquare] = useState(0.025);
  const [model, setModel] = useState<Lens["model"]>("pinhole");
  const [charuco, setCharuco] = useState(false);
  const [marker, setMarker] = useState(0.018);
  const [dictionary, setDictionary] = useState("DICT_4X4_50");
  const [result, setResult] = useState<Schemas["IntrinsicsRead"] | null>(null);
  const [pasted, setPasted] = useState(lens ? JSON.stringify(lens) : "");
  const [busy, setBusy] = useState(false);
  const [error, run] = useErrors();

  const choose = (next: Source) => {
    setSource(next);
    if (next === "none") onLens(null, null);
  };
  const calibrate = () =>
    void run(async () => {
      setBusy(true);
      try {
        const found = await postIntrinsics(
          intrinsicsForm(files, cols, rows, square, model, charuco ? { markerM: marker, dictionary } : null),
        );
        setResult(found);
        onLens(found.lens, { width: found.width, height: found.height });
      } finally {
        setBusy(false);
      }
    });
  const applyPasted = () =>
    void run(async () => {
      onLens(parseLens(pasted), null);
      await Promise.resolve();
    });

  return (
    <section data-testid="camera-lens">
      <h3>Lens</h3>
      <div className="row">
        {(
          [
            ["none", "None (pinhole)"],
            ["board", "Board images"],
            ["paste", "Paste"],
          ] as const
        ).map(([value, label]) => (
          <label key={value}>
            <input
              type="radio"
              name="lens-source"
              checked={source === value}
              onChange={() => choose(value)}
              data-testid={`camera-lens-${value}`}
            />{" "}
            {label}
          </label>
        ))}
      </div>
      {source === "board" && (
        <>
          <div className="row">
            <label className="filebutton">
              Board images…
              <input
                type="file"
                multiple
                accept="image/png,image/jpeg"
                data-testid="camera-board-input"
                onChange={(e) => setFiles(Array.from(e.target.files ?? []))}
              />
            </label>
            <span className="muted">{files.length} chosen</span>
          </div>
          <div className="row">
            <select
              value={charuco ? "charuco" : "chessboard"}
              onChange={(e) => setCharuco(e.target.value === "charuco")}
              data-testid="camera-board-kind"
            >
              <option value="chessboard">chessboard</option>
              <option value="charuco">ChArUco</option>
            </select>
            {charuco && (
              <>
                marker m
                <input
                  className="small"
                  type="number"
                  step="0.001"
                  min={0}
                  value={marker}
                  onChange={(e) => setMarker(+e.target.value)}
                  data-testid="camera-board-marker"
                />
                <select value={dictionary} onChange={(e) => setDictionary(e.target.value)}>
                  {CHARUCO_DICTIONARIES.map((d) => (
                    <option key={d}>{d}</option>
                  ))}
                </select>
              </>
            )}
          </div>
          <div className="row">
            inner corners
            <input className="small" type="number" min={2} value={cols} onChange={(e) => setCols(+e.target.value)} />x
            <input className="small" type="number" min={2} value={rows} onChange={(e) => setRows(+e.target.value)} />
            square m
            <input
              className="small"
              type="number"
              step="0.001"
              min={0}
              value={square}
              onChange={(e) => setSquare(+e.target.value)}
            />
            <select value={model} onChange={(e) => setModel(e.target.value as Lens["model"])}>
              <option value="pinhole">pinhole</option>
              <option value="fisheye">fisheye</option>
            </select>
            <button className="primary" disabled={busy || files.length === 0} onClick={calibrate}>
              {busy ? "Calibrating…" : "Calibrate"}
            </button>
          </div>
          {result && (
            <div data-testid="camera-intrinsics">
              <div>
                {result.width}x{result.height}, RMS {result.rms_px.toFixed(3)} px over {result.views.length} views
              </div>
              <table>
                <tbody>
                  {result.views.map((v) => (
                    <tr key={v.name}>
                      <td>{v.name}</td>
                      <td className="num">{v.rms_px.toFixed(3)} px</td>
                    </tr>
                  ))}
                </tbody>
              </table>
              {result.skipped.length > 0 && (
                <div className="muted">Board not found in: {result.skipped.join(", ")}</div>
              )}
            </div>
          )}
        </>
      )}
      {source === "paste" && (
        <>
          <textarea
            rows={4}
            placeholder='{"model": "fisheye", "K": [[...], [...], [0, 0, 1]], "distortion": [...]}'
            value={pasted}
            onChange={(e) => setPasted(e.target.value)}
            data-testid="camera-lens-text"
          />
          <button onClick={applyPasted}>Use this lens</button>
        </>
      )}
      {lens && source !== "none" && (
        <div className="muted" data-testid="camera-lens-current">
          Lens in use: {lens.model}, f {(lens.K[0]?.[0] ?? 0).toFixed(1)} px
        </div>
      )}
      {error && (
        <div className="error" role="alert">
          {error}
        </div>
      )}
    </section>
  );
}

// Fit the ground: the mounting facts the fit cannot know (measured on the vehicle: y_c, and whether the camera
// looks ahead or behind, forward_sign +1 or -1), the Fit button, and the
// fitted values (k_x, k_y, y_h, the ROI) or the server's refusal, shown beside the button; the form is kept.
import type { GroundRead, Mount } from "../../lib/cameraSetup";

interface Props {
  mount: Mount;
  onMount: (mount: Mount) => void;
  /** Why the fit cannot be asked for yet (e.g. too few points), or null. */
  blocked: string | null;
  busy: boolean;
  onFit: () => void;
  /** The fit of the current points, null when there is none or the points changed since. */
  fit: GroundRead | null;
  error: string | null;
}

export function GroundFit({ mount, onMount, blocked, busy, onFit, fit, error }: Props) {
  return (
    <section data-testid="camera-fit">
      <h3>Ground</h3>
      <div className="row">
        <label title="Metres from the rear axle to the camera, along the way the camera looks">
          y_c m{" "}
          <input
            className="small"
            type="number"
            step="0.01"
            value={mount.y_c}
            onChange={(e) => onMount({ ...mount, y_c: Number(e.target.value) })}
            data-testid="camera-y-c"
          />
        </label>
        <label title="Which way along the vehicle the camera looks: ahead (the floor moves down the image as the vehicle drives forward) or behind (it moves up)">
          camera looks{" "}
          <select
            value={mount.forward_sign}
            onChange={(e) => onMount({ ...mount, forward_sign: Number(e.target.value) === -1 ? -1 : 1 })}
            data-testid="camera-looks"
          >
            <option value={1}>ahead (forward_sign +1)</option>
            <option value={-1}>behind (forward_sign −1)</option>
          </select>
        </label>
      </div>
      <div className="row">
        <button
          className="primary"
          disabled={busy || blocked !== null}
          title={blocked ?? "Fit the ground plane to the points"}
          onClick={onFit}
          data-testid="camera-fit-button"
        >
          {busy ? "Fitting…" : "Fit ground"}
        </button>
        {blocked && <span className="muted">{blocked}</span>}
      </div>
      {error && (
        <div className="alert" role="alert" data-testid="camera-fit-error">
          {error}
        </div>
      )}
      {fit && (
        <table data-testid="camera-fit-result">
          <tbody>
            <tr>
              <td>k_x</td>
              <td className="num" data-testid="camera-k-x">
                {fit.k_x.toFixed(5)} m/px
              </td>
            </tr>
            <tr>
              <td>k_y</td>
              <td className="num" data-testid="camera-k-y">
                {fit.k_y.toFixed(5)} m/px
              </td>
            </tr>
            <tr>
              <td>y_h</td>
              <td className="num" data-testid="camera-y-h">
                {fit.y_h.toFixed(3)} m
              </td>
            </tr>
            <tr>
              <td>ground ROI</td>
              <td className="num">{fit.ground_roi.join(", ")}</td>
            </tr>
            <tr>
              <td>largest residual</td>
              <td className="num">{Math.max(...fit.residuals_m).toFixed(3)} m</td>
            </tr>
          </tbody>
        </table>
      )}
    </section>
  );
}

// The clicked floor points: each one's pixel in the frame, its floor position (typed, metres in the camera's look
// frame: along the way the camera looks and to its left, from the floor under the camera), its residual after a
// fit (colour-coded), and a delete button.
import type { Dispatch } from "react";
import type { PointRow, PointsAction } from "../../lib/cameraSetup";

const GOOD_M = 0.05; // a residual below this is green, below FAIR_M amber, above red
const FAIR_M = 0.2;

function residualClass(r: number | null): string {
  if (r === null) return "res-none";
  return r < GOOD_M ? "res-good" : r < FAIR_M ? "res-fair" : "res-bad";
}

export function PointsTable({ rows, dispatch }: { rows: PointRow[]; dispatch: Dispatch<PointsAction> }) {
  if (rows.length === 0) {
    return <p className="muted">No points yet: pick “Points” and click at least four floor marks on the frame.</p>;
  }
  return (
    <>
      <p className="hint" data-testid="camera-look-frame">
        Floor positions are in the camera&apos;s look frame: metres from the floor under the camera, x along the way the
        camera looks, y to its left. For a camera looking behind the vehicle, marks behind it have positive x.
      </p>
      <table data-testid="camera-points">
        <thead>
          <tr>
            <th className="num">#</th>
            <th className="num">pixel x</th>
            <th className="num">pixel y</th>
            <th title="Metres along the floor the way the camera looks, from the floor under the camera">
              x_m (the way it looks)
            </th>
            <th title="Metres to the left of the way the camera looks">y_m (to its left)</th>
            <th className="num">residual</th>
            <th />
          </tr>
        </thead>
        <tbody>
          {rows.map((r, i) => (
            <tr key={r.id} data-testid={`camera-point-${i + 1}`}>
              <td className="num">{i + 1}</td>
              <td className="num">{r.px.toFixed(1)}</td>
              <td className="num">{r.py.toFixed(1)}</td>
              {(["x_m", "y_m"] as const).map((field) => (
                <td key={field}>
                  <input
                    className="metres"
                    inputMode="decimal"
                    aria-label={`point ${i + 1} ${field}`}
                    data-testid={`camera-point-${i + 1}-${field}`}
                    value={r[field]}
                    onChange={(e) => dispatch({ type: "edit", id: r.id, field, value: e.target.value })}
                  />
                </td>
              ))}
              <td className={`num ${residualClass(r.residual_m)}`} data-testid={`camera-point-${i + 1}-residual`}>
                {r.residual_m === null ? "—" : `${r.residual_m.toFixed(3)} m`}
              </td>
              <td>
                <button
                  className="danger"
                  title="Delete this point"
                  data-testid={`camera-point-${i + 1}-delete`}
                  onClick={() => dispatch({ type: "remove", id: r.id })}
                >
                  ✕
                </button>
              </td>
            </tr>
          ))}
        </tbody>
      </table>
    </>
  );
}

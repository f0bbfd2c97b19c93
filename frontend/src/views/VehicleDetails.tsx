// The selected vehicle's details: its latest estimate (position, confidence in its band, heading, speed and
// motion as the server reports them, "—" when unknown; an "appearance only" badge without camera odometry),
// the camera check, the set-start control (actions), the latest frame, replay (children) and the recent history.
import { useEffect, useState, type ReactNode } from "react";
import { apiGet, type Schemas } from "../api/client";
import { bandCss, confidenceBand, formatConfidence } from "../lib/confidence";
import { formatBearing, formatMotion, formatSpeed } from "../lib/motion";
import { statusOf, type VehicleState } from "../lib/liveState";
import { formatFrameTime, formatTime } from "../lib/time";
import { LatestFrame } from "./LatestFrame";
import { PointReadout } from "../map/PointReadout";
import type { SiteCoordinates } from "../lib/siteCoordinates";
import { VehicleSwatch } from "./VehicleList";

export const HISTORY_S = 300; // the history: the last five minutes of frame time

/** "appearance only" when the estimate was made without the vehicle's camera odometry. */
export function AppearanceOnlyBadge({ odometry }: { odometry: boolean | undefined }) {
  if (odometry !== false) return null;
  return (
    <span
      className="badge"
      data-testid="appearance-only"
      title={
        "Camera odometry was not used: the position comes from recognising the place alone, " +
        "so it can jump between places and has no measured heading or speed"
      }
    >
      appearance only
    </span>
  );
}

/** The confidence as a percentage in its band's colour (the same everywhere). */
export function Confidence({ value, lost, stale }: { value: number; lost: boolean; stale: boolean }) {
  const band = confidenceBand(value, lost, stale);
  return (
    <span className={`conf conf-${band}`} style={{ color: bandCss(band) }} data-band={band}>
      {formatConfidence(value)}
    </span>
  );
}

interface Props {
  v: VehicleState;
  /** Shown right under the estimate (the set-start control). */
  actions?: ReactNode;
  /** Shown under the latest frame (the replay). */
  children?: ReactNode;
  /** The site's coordinates: the position on the mine grid and in longitude/latitude too. */
  coords?: SiteCoordinates | null;
}

export function VehicleDetails({ v, actions, children, coords = null }: Props) {
  const [history, setHistory] = useState<Schemas["PositionRead"][]>([]);
  const seq = v.position?.seq;
  const since = v.position ? v.position.t - HISTORY_S : null;
  useEffect(() => {
    let cancelled = false;
    apiGet("/api/vehicles/{vehicle_id}/positions", { vehicle_id: v.id }, { start: since })
      .then((rows) => !cancelled && setHistory(rows.slice(-12).reverse()))
      .catch(() => !cancelled && setHistory([]));
    return () => {
      cancelled = true;
    };
  }, [v.id, seq, since]);
  const p = v.position;
  const travel = p !== null && p.yaw === null && v.heading !== null;
  return (
    <section data-testid="vehicle-details">
      <h3>
        <VehicleSwatch id={v.id} />
        {v.name} {p && <AppearanceOnlyBadge odometry={p.odometry} />}
      </h3>
      {p ? (
        <table>
          <tbody>
            <tr>
              <th>Status</th>
              <td>{statusOf(v)}</td>
            </tr>
            <tr>
              <th>Position</th>
              <td data-testid="detail-position">
                <PointReadout x={p.x} y={p.y} coords={coords} testId="vehicle" />
              </td>
            </tr>
            <tr data-testid="detail-confidence">
              <th>Confidence</th>
              <td>
                <Confidence value={p.confidence} lost={p.lost} stale={v.stale} />{" "}
                <span className="muted">{p.lost ? "(lost)" : p.matched ? "(matched)" : "(unmatched)"}</span>
              </td>
            </tr>
            <tr data-testid="detail-heading">
              <th>Heading</th>
              <td title="Grid bearing, clockwise from grid north">
                {formatBearing(v.heading)}
                {travel && <span className="muted"> (direction of travel)</span>}
              </td>
            </tr>
            <tr data-testid="detail-speed">
              <th>Speed</th>
              <td>{formatSpeed(p.speed_mps)}</td>
            </tr>
            <tr data-testid="detail-motion">
              <th>Motion</th>
              <td>{formatMotion(p.moving)}</td>
            </tr>
            <tr data-testid="detail-odometry">
              <th>Odometry</th>
              <td>{p.odometry === undefined ? "—" : p.odometry ? "camera odometry" : "none (appearance only)"}</td>
            </tr>
            <tr>
              <th>Node</th>
              <td>{p.node}</td>
            </tr>
            <tr data-testid="camera-check" data-obscured={p.obscured ? "yes" : "no"}>
              <th>Camera</th>
              <td>
                {p.obscured === null || p.obscured === undefined ? (
                  "—"
                ) : (
                  <>
                    {p.obscured ? `obscured (${p.obscured_reason ?? "?"})` : "clear"}
                    <div className="muted" style={{ fontSize: 11 }}>
                      salient {(p.salient ?? 0).toFixed(2)} · speckle {((p.speckle ?? 0) * 100).toFixed(1)} % · flat{" "}
                      {((p.flat_area ?? 0) * 100).toFixed(1)} %
                    </div>
                  </>
                )}
              </td>
            </tr>
            <tr>
              <th>Frame time</th>
              <td>{formatFrameTime(p.t)}</td>
            </tr>
            <tr>
              <th>Received</th>
              <td>{formatTime(p.received_at)}</td>
            </tr>
          </tbody>
        </table>
      ) : (
        <p className="muted">No position yet.</p>
      )}
      {actions}
      {/* keyed apart from its siblings (the replay panel is keyed by the vehicle id): two children with one
          key leave the old vehicle's picture behind */}
      <LatestFrame key={`latest-frame-${v.id}`} vehicleId={v.id} name={v.name} seq={seq} />
      {children}
      <h3>History</h3>
      <table data-testid="vehicle-history">
        <thead>
          <tr>
            <th className="num">t</th>
            <th className="num">E</th>
            <th className="num">N</th>
            <th className="num">Conf.</th>
            <th className="num">Speed</th>
          </tr>
        </thead>
        <tbody>
          {history.map((h) => (
            <tr key={h.seq}>
              <td className="num">{formatFrameTime(h.t)}</td>
              <td className="num">{h.x.toFixed(1)}</td>
              <td className="num">{h.y.toFixed(1)}</td>
              <td className="num">
                <Confidence value={h.confidence} lost={h.lost} stale={false} />
              </td>
              <td className="num">{formatSpeed(h.speed_mps)}</td>
            </tr>
          ))}
        </tbody>
      </table>
    </section>
  );
}

// Live monitoring: REST snapshot, then the /api/live WebSocket (auto-reconnect with resume); vehicles on the
// plan and in a list with their status; alerts for lost vehicles and obscured cameras; click one for its
// latest estimate, camera check and history, and replay any time range of it (ReplayPanel, ReplayLayer).
import { useEffect, useMemo, useRef, useState, type ReactNode } from "react";
import { apiGet, getToken, type Schemas } from "../api/client";
import { MineMap } from "../map/MineMap";
import { VehicleLayer } from "../map/VehicleLayer";
import { alertsOf, LiveState, speedOf, statusOf, withHeading, type VehicleState } from "../lib/liveState";
import { ReplayLayer } from "../map/ReplayLayer";
import { EPOCH_CLOCK_S, formatClock } from "../lib/replay";
import { LatestFrame } from "./LatestFrame";
import { ReplayPanel, type ReplaySession } from "./ReplayPanel";
import { LiveSocket, type ConnectionState } from "../lib/liveSocket";
import { confidenceColour, rgbCss, STALE_GREY } from "../lib/colours";

const HISTORY_S = 300; // the details panel's history: the last five minutes of frame time

function liveUrl(since: number | null): string {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const query = new URLSearchParams({ token: getToken() ?? "" });
  if (since !== null) query.set("since", String(since));
  return `${scheme}://${location.host}/api/live?${query.toString()}`;
}

export function MonitorView({ siteId }: { siteId: number }) {
  const state = useRef(new LiveState());
  const [version, setVersion] = useState(0);
  const [connection, setConnection] = useState<ConnectionState>("connecting");
  const [selectedId, setSelectedId] = useState<number | null>(null);
  const [replay, setReplay] = useState<ReplaySession | null>(null);

  useEffect(() => {
    let cancelled = false;
    let pending = false;
    const bump = () => {
      if (pending) return;
      pending = true;
      requestAnimationFrame(() => {
        pending = false;
        if (!cancelled) setVersion((v) => v + 1);
      });
    };
    const socket = new LiveSocket({
      url: liveUrl,
      lastSeq: () => state.current.resumeSeq(),
      onMessage: (m) => {
        state.current.apply(m);
        bump();
      },
      onState: (s) => !cancelled && setConnection(s),
    });
    (async () => {
      try {
        const latest = await apiGet("/api/positions/latest");
        if (cancelled) return;
        const seq = Math.max(0, ...latest.map((v) => v.position?.seq ?? 0));
        state.current.apply({ type: "snapshot", seq, stale_after_s: state.current.staleAfterS, vehicles: latest });
        bump();
      } catch {
        /* the WebSocket snapshot follows anyway */
      }
      if (!cancelled) socket.start();
    })();
    return () => {
      cancelled = true;
      socket.stop();
    };
  }, []);

  const vehicles = useMemo(
    () => state.current.sorted().filter((v) => v.siteId === siteId),
    // eslint-disable-next-line react-hooks/exhaustive-deps
    [version, siteId],
  );
  const drawn = useMemo(() => vehicles.map(withHeading), [vehicles]);
  const selected = vehicles.find((v) => v.id === selectedId) ?? null;
  const alerts = alertsOf(vehicles);

  return (
    <>
      <MineMap
        key={siteId}
        siteId={siteId}
        overlay={(ctx) => (
          <>
            <VehicleLayer ctx={ctx} vehicles={drawn} selectedId={selectedId} onSelect={setSelectedId} />
            {replay && <ReplayLayer ctx={ctx} session={replay} />}
          </>
        )}
      />
      <aside className="side">
        <div className="row">
          <h2 style={{ margin: 0 }}>Vehicles</h2>
          <span className="spacer" />
          <span className={`conn ${connection}`} data-testid="live-connection">
            {connection === "open" ? "live" : connection}
          </span>
        </div>
        {alerts.lost.length > 0 && (
          <div className="alert" data-testid="lost-alert" role="alert">
            Lost: {alerts.lost.join(", ")}
          </div>
        )}
        {alerts.obscured.length > 0 && (
          <div className="alert" data-testid="obscured-alert" role="alert">
            Camera obscured: {alerts.obscured.map((o) => `${o.name} (${o.reason})`).join(", ")}
          </div>
        )}
        <table className="vehicle-list" data-testid="vehicle-list">
          <thead>
            <tr>
              <th>Name</th>
              <th>Status</th>
              <th className="num">Conf.</th>
              <th className="num">E</th>
              <th className="num">N</th>
            </tr>
          </thead>
          <tbody>
            {vehicles.map((v) => (
              <VehicleRow key={v.id} v={v} selected={v.id === selectedId} onClick={() => setSelectedId(v.id)} />
            ))}
          </tbody>
        </table>
        {vehicles.length === 0 && <p className="muted">No vehicles on this site.</p>}
        {selected && (
          <VehicleDetails v={selected}>
            <ReplayPanel key={selected.id} vehicle={selected} session={replay} onSession={setReplay} />
          </VehicleDetails>
        )}
      </aside>
    </>
  );
}

function VehicleRow({ v, selected, onClick }: { v: VehicleState; selected: boolean; onClick: () => void }) {
  const status = statusOf(v);
  const p = v.position;
  const colour = v.stale || !p ? STALE_GREY : confidenceColour(p.confidence);
  return (
    <tr
      className={selected ? "selected" : ""}
      onClick={onClick}
      data-testid={`vehicle-row-${v.name}`}
      data-status={status}
      data-seq={p?.seq ?? ""}
    >
      <td>
        <span className="dot" style={{ background: rgbCss(colour) }} />
        {v.name}
      </td>
      <td>
        <span
          className={`status ${status.replace(" ", "-")}`}
          style={status === "camera obscured" ? { color: "var(--fair)" } : undefined}
        >
          {status}
        </span>
      </td>
      <td className="num">{p ? p.confidence.toFixed(2) : "–"}</td>
      <td className="num">{p ? p.x.toFixed(1) : "–"}</td>
      <td className="num">{p ? p.y.toFixed(1) : "–"}</td>
    </tr>
  );
}

function VehicleDetails({ v, children }: { v: VehicleState; children?: ReactNode }) {
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
  return (
    <section data-testid="vehicle-details">
      <h3>{v.name}</h3>
      {p ? (
        <table>
          <tbody>
            <tr><th>Status</th><td>{statusOf(v)}</td></tr>
            <tr><th>Position</th><td>E {p.x.toFixed(2)} N {p.y.toFixed(2)}</td></tr>
            <tr><th>Heading</th><td>{v.heading === null ? "–" : `${((v.heading * 180) / Math.PI).toFixed(0)}°${p.yaw === null ? " (travel)" : ""}`}</td></tr>
            <tr><th>Confidence</th><td>{p.confidence.toFixed(2)} {p.matched ? "(matched)" : "(unmatched)"}</td></tr>
            <tr><th>Speed</th><td>{speedOf(v).toFixed(2)} m/s</td></tr>
            <tr><th>Node</th><td>{p.node}</td></tr>
            <tr data-testid="camera-check" data-obscured={p.obscured ? "yes" : "no"}>
              <th>Camera</th>
              <td>
                {p.obscured === null || p.obscured === undefined ? (
                  "–"
                ) : (
                  <>
                    {p.obscured ? `obscured (${p.obscured_reason ?? "?"})` : "clear"}
                    <div className="muted" style={{ fontSize: 11 }}>
                      salient {(p.salient ?? 0).toFixed(2)} · speckle {((p.speckle ?? 0) * 100).toFixed(1)} % ·
                      flat {((p.flat_area ?? 0) * 100).toFixed(1)} %
                    </div>
                  </>
                )}
              </td>
            </tr>
            <tr><th>Frame time</th><td>{formatClock(p.t)}{p.t < EPOCH_CLOCK_S ? " s" : ""}</td></tr>
            <tr><th>Received</th><td>{new Date(p.received_at).toLocaleTimeString()}</td></tr>
          </tbody>
        </table>
      ) : (
        <p className="muted">No position yet.</p>
      )}
      <LatestFrame key={v.id} vehicleId={v.id} seq={seq} />
      {children}
      <h3>History</h3>
      <table data-testid="vehicle-history">
        <thead>
          <tr><th className="num">t</th><th className="num">E</th><th className="num">N</th><th className="num">Conf.</th></tr>
        </thead>
        <tbody>
          {history.map((h) => (
            <tr key={h.seq}>
              <td className="num">{formatClock(h.t)}</td>
              <td className="num">{h.x.toFixed(1)}</td>
              <td className="num">{h.y.toFixed(1)}</td>
              <td className="num">{h.confidence.toFixed(2)}</td>
            </tr>
          ))}
        </tbody>
      </table>
    </section>
  );
}

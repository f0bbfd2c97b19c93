// Live monitoring: REST snapshot, then the /api/live WebSocket (auto-reconnect with resume); vehicles on the
// plan and in a list, each in its own colour (name, trail, swatch) with its confidence in bands (marker, list;
// a legend of both); alerts for lost vehicles and obscured cameras; the
// server's event log to acknowledge (EventsPanel, a beep on new events when turned on); click
// one for its details (VehicleDetails), place its known start (SetStart, surveyors and admins), replay any
// time range of it (ReplayPanel, ReplayLayer) and export position history (PositionsExport).
import { useEffect, useMemo, useState } from "react";
import { apiGet, getToken } from "../api/client";
import { MineMap } from "../map/MineMap";
import { VehicleLayer } from "../map/VehicleLayer";
import { StartLayer } from "../map/StartLayer";
import { alertsOf, LiveState, withHeading } from "../lib/liveState";
import { ReplayLayer } from "../map/ReplayLayer";
import { ReplayPanel, type ReplaySession } from "./ReplayPanel";
import { LiveSocket, type ConnectionState } from "../lib/liveSocket";
import { BAND_LABELS } from "../lib/confidence";
import { TRAIL_DASH, TRAIL_LABELS } from "../lib/vehicleColours";
import { HISTORY_S, VehicleDetails } from "./VehicleDetails";
import { SetStartPanel, useSetStart } from "./SetStart";
import { BandDot, VehicleList } from "./VehicleList";
import { PositionsExport } from "./PositionsExport";
import { useSiteCoordinates } from "../map/siteCrs";
import { EventLog, type EventRow } from "../lib/eventLog";
import { beep } from "../lib/beep";
import { useLatest } from "../lib/useLatest";
import { EventsPanel, useEventSound } from "./EventsPanel";

function liveUrl(since: number | null): string {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const query = since === null ? "" : `?${new URLSearchParams({ since: String(since) }).toString()}`;
  return `${scheme}://${location.host}/api/live${query}`;
}

/** The socket's first message: the login token (never in the URL, which servers and proxies log). */
function authMessage(): string | null {
  const token = getToken();
  return token ? JSON.stringify({ type: "auth", token }) : null;
}

/** A short line in a trail's dash (neutral colour): the legend's sample. */
function DashSample({ dash }: { dash: number[] | undefined }) {
  return (
    <svg className="dash-sample" width="22" height="8" aria-hidden="true">
      <line x1="1" y1="4" x2="21" y2="4" strokeWidth="2.5" strokeDasharray={dash?.join(" ")} />
    </svg>
  );
}

/** On the map: the markers' confidence bands and the trails' vehicle colours and dashes. */
function ConfidenceLegend() {
  return (
    <div className="overlay-box legend" data-testid="confidence-legend">
      <div className="muted">Marker: position confidence</div>
      {BAND_LABELS.map(([band, label]) => (
        <div key={band} data-band={band}>
          <BandDot band={band} />
          {label}
        </div>
      ))}
      <div className="muted" data-testid="trail-legend">
        Name and trail: the vehicle&apos;s colour
      </div>
      {TRAIL_LABELS.map(([band, label]) => (
        <div key={band} data-trail-band={band}>
          <DashSample dash={TRAIL_DASH[band]} />
          {label}
        </div>
      ))}
    </div>
  );
}

export function MonitorView({ siteId, editable }: { siteId: number; editable: boolean }) {
  // one long-lived model, mutated by the socket's messages; `version` below is what re-renders
  const [state] = useState(() => new LiveState());
  const [version, setVersion] = useState(0);
  const [connection, setConnection] = useState<ConnectionState>("connecting");
  const [selectedId, setSelectedId] = useState<number | null>(null);
  const [replay, setReplay] = useState<ReplaySession | null>(null);
  const [follow, setFollow] = useState(false);
  const [events] = useState(() => new EventLog());
  const [sound, setSound] = useEventSound();
  const alarm = useLatest({ sound, siteId }); // read by the socket's handler, set up once

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
      authMessage,
      lastSeq: () => state.resumeSeq(),
      onMessage: (m) => {
        if (m.type === "snapshot") events.reset(m.events ?? []);
        else if (m.type === "event" && events.apply(m)) {
          if (alarm.current.sound && m.site_id === alarm.current.siteId) beep();
        }
        state.apply(m);
        bump();
      },
      onState: (s) => !cancelled && setConnection(s),
    });
    void (async () => {
      try {
        const latest = await apiGet("/api/positions/latest");
        if (cancelled) return;
        const seq = Math.max(0, ...latest.map((v) => v.position?.seq ?? 0));
        state.apply({ type: "snapshot", seq, stale_after_s: state.staleAfterS, vehicles: latest });
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
  }, [state, events, alarm]);

  const vehicles = useMemo(
    () => state.sorted().filter((v) => v.siteId === siteId),
    // eslint-disable-next-line react-hooks/exhaustive-deps
    [version, siteId],
  );
  const drawn = useMemo(() => vehicles.map(withHeading), [vehicles]);
  const selected = vehicles.find((v) => v.id === selectedId) ?? null;
  const coords = useSiteCoordinates(siteId);
  const alerts = alertsOf(vehicles);
  const setStart = useSetStart(editable ? (selected?.id ?? null) : null);
  const placedStart = setStart.result?.state === "accepted" ? setStart.result.start : null;
  const acknowledged = (event: EventRow) => {
    events.apply(event);
    setVersion((v) => v + 1);
  };

  return (
    <>
      <MineMap
        key={siteId}
        siteId={siteId}
        onMapClick={setStart.placing ? setStart.place : undefined}
        overlay={(ctx) => (
          <>
            <VehicleLayer
              ctx={ctx}
              vehicles={drawn}
              selectedId={selectedId}
              onSelect={setSelectedId}
              selectable={!setStart.placing}
              follow={follow && !replay?.follow ? selectedId : null}
              onFollowEnd={() => setFollow(false)}
            />
            <StartLayer ctx={ctx} start={placedStart} placing={setStart.placing} />
            {replay && <ReplayLayer ctx={ctx} session={replay} />}
            <ConfidenceLegend />
          </>
        )}
      />
      <aside className="side">
        <div className="row">
          <h2 style={{ margin: 0 }}>Vehicles</h2>
          <span className="spacer" />
          <label title="Keep the map centred on the selected vehicle (a drag of the map stops it)">
            <input
              type="checkbox"
              data-testid="follow-toggle"
              checked={follow}
              disabled={selected === null}
              onChange={(e) => setFollow(e.target.checked)}
            />{" "}
            follow
          </label>
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
        <EventsPanel
          key={siteId}
          siteId={siteId}
          log={events}
          vehicles={vehicles}
          sound={sound}
          onSound={setSound}
          onAcknowledged={acknowledged}
        />
        <VehicleList vehicles={vehicles} selectedId={selectedId} onSelect={setSelectedId} />
        <PositionsExport
          siteId={siteId}
          vehicles={vehicles}
          selected={selected}
          replay={replay}
          historyS={HISTORY_S}
          trailS={state.trailWindowS}
        />
        {selected && (
          <VehicleDetails v={selected} coords={coords} actions={editable && <SetStartPanel control={setStart} />}>
            <ReplayPanel key={`replay-${selected.id}`} vehicle={selected} session={replay} onSession={setReplay} />
          </VehicleDetails>
        )}
      </aside>
    </>
  );
}

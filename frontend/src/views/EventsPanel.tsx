// The monitoring page's events panel: the site's unacknowledged events (they stay until someone acknowledges
// them, even after their condition ended), each with an Acknowledge button; below them the latest acknowledged
// ones with who and when (anyone's, as the live socket reports them). Filters by vehicle and kind, a CSV export
// of the site's log with those filters, and an optional beep on new events (off by default, kept per browser).
import { useState, type ReactNode } from "react";
import { ApiError, apiPost } from "../api/client";
import {
  END_LABELS,
  eventsCsvUrl,
  kindLabel,
  KIND_LABELS,
  type EventFilters,
  type EventKind,
  type EventLog,
  type EventRow,
} from "../lib/eventLog";
import { unlockAudio } from "../lib/beep";
import type { VehicleState } from "../lib/liveState";
import { formatTime } from "../lib/time";
import { DownloadStatus, useDownload } from "./useDownload";

const SOUND_KEY = "driftmap.eventSound";

/** The beep toggle, off unless this browser turned it on before. */
export function useEventSound(): [boolean, (on: boolean) => void] {
  const [on, setOn] = useState(() => {
    try {
      return localStorage.getItem(SOUND_KEY) === "on";
    } catch {
      return false;
    }
  });
  const set = (value: boolean) => {
    if (value) unlockAudio(); // inside the click: browsers allow audio from here on
    try {
      localStorage.setItem(SOUND_KEY, value ? "on" : "off");
    } catch {
      /* private mode: the choice lasts this page */
    }
    setOn(value);
  };
  return [on, set];
}

interface Props {
  siteId: number;
  log: EventLog;
  /** The site's vehicles (the vehicle filter's choices). */
  vehicles: VehicleState[];
  sound: boolean;
  onSound: (on: boolean) => void;
  /** An acknowledgement answered by the server (the event as it now is). */
  onAcknowledged: (event: EventRow) => void;
}

export function EventsPanel({ siteId, log, vehicles, sound, onSound, onAcknowledged }: Props) {
  const [filters, setFilters] = useState<EventFilters>({ vehicleId: null, kind: null });
  const [busy, setBusy] = useState<number | null>(null);
  const [error, setError] = useState<string | null>(null);
  const download = useDownload();
  const pending = log.pending(siteId, filters);
  const done = log.acknowledged(siteId, filters);

  const acknowledge = async (id: number) => {
    setBusy(id);
    setError(null);
    try {
      onAcknowledged(await apiPost("/api/events/{event_id}/ack", { event_id: id }));
    } catch (e) {
      setError(e instanceof ApiError ? `Not acknowledged: ${e.message}` : `Not acknowledged: ${String(e)}`);
    } finally {
      setBusy(null);
    }
  };

  return (
    <section className="events" data-testid="events-panel" data-pending={pending.length}>
      <div className="row">
        <h3 style={{ margin: 0 }}>
          Events{" "}
          {pending.length > 0 && (
            <span className="badge count" data-testid="events-count">
              {pending.length}
            </span>
          )}
        </h3>
        <span className="spacer" />
        <label title="Beep when a new event opens">
          <input
            type="checkbox"
            data-testid="events-sound"
            checked={sound}
            onChange={(e) => onSound(e.target.checked)}
          />{" "}
          Sound
        </label>
      </div>
      <div className="row">
        <select
          data-testid="events-vehicle"
          value={filters.vehicleId ?? ""}
          onChange={(e) => setFilters({ ...filters, vehicleId: e.target.value ? Number(e.target.value) : null })}
        >
          <option value="">all vehicles</option>
          {vehicles.map((v) => (
            <option key={v.id} value={v.id}>
              {v.name}
            </option>
          ))}
        </select>
        <select
          data-testid="events-kind"
          value={filters.kind ?? ""}
          onChange={(e) => setFilters({ ...filters, kind: (e.target.value || null) as EventKind | null })}
        >
          <option value="">all kinds</option>
          {KIND_LABELS.map(([kind, label]) => (
            <option key={kind} value={kind}>
              {label}
            </option>
          ))}
        </select>
        <span className="spacer" />
        <button
          data-testid="events-csv"
          disabled={download.busy}
          title="The site's whole event log with these filters, as CSV"
          onClick={() => void download.run(eventsCsvUrl(siteId, filters), "events.csv")}
        >
          CSV
        </button>
      </div>
      <DownloadStatus download={download} testId="events-csv" />
      {error && (
        <div className="error" role="alert">
          {error}
        </div>
      )}
      <ul className="event-list" data-testid="events-pending">
        {pending.map((e) => (
          <EventItem key={e.id} e={e}>
            <button data-testid="event-ack" disabled={busy === e.id} onClick={() => void acknowledge(e.id)}>
              Acknowledge
            </button>
          </EventItem>
        ))}
      </ul>
      {pending.length === 0 && <p className="muted">No unacknowledged events.</p>}
      {done.length > 0 && (
        <>
          <div className="muted">Acknowledged</div>
          <ul className="event-list done" data-testid="events-acknowledged">
            {done.map((e) => (
              <EventItem key={e.id} e={e}>
                <span className="muted" data-testid="event-acknowledged-by">
                  ✓ {e.acknowledged_by ?? "?"} {formatTime(e.acknowledged_at!)}
                </span>
              </EventItem>
            ))}
          </ul>
        </>
      )}
    </section>
  );
}

/** One event: start time, vehicle, kind and detail, and how it ended (or that it goes on). */
function EventItem({ e, children }: { e: EventRow; children: ReactNode }) {
  const ended = e.ended_at !== null;
  const instant = e.kind === "start_known";
  const where = e.x !== null && e.y !== null ? `at E ${e.x.toFixed(1)} / N ${e.y.toFixed(1)}` : "position unknown";
  return (
    <li
      data-testid={`event-row-${e.id}`}
      data-kind={e.kind}
      data-vehicle={e.vehicle}
      data-open={!ended}
      data-acknowledged={e.acknowledged_at !== null}
      className={ended ? "ended" : "open"}
      title={where}
    >
      <div>
        <span className="time">{formatTime(e.started_at)}</span> <strong>{e.vehicle}</strong> {kindLabel(e.kind)}
        {e.detail && <span className="muted"> ({e.detail})</span>}
      </div>
      <div className="row event-end">
        <span className={ended ? "muted" : "ongoing"}>
          {instant ? "" : ended ? `${END_LABELS[e.kind]} ${formatTime(e.ended_at!)}` : "ongoing"}
        </span>
        <span className="spacer" />
        {children}
      </div>
    </li>
  );
}

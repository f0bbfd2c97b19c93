// "Export positions" on the monitoring page: the position history of one vehicle (the selected one by default)
// or of all, in a format, over a time range that follows what the view shows until it is edited (a loaded
// replay's range; else the selected vehicle's history window; for all vehicles the trail window), downloaded from
// GET /api/sites/{id}/positions/export with the login token; a refusal shows the server's reason.
import { useState } from "react";
import { buildUrl } from "../api/client";
import { POSITION_FORMATS, rangeQuery, shownRange, type PositionFormat } from "../lib/exports";
import type { VehicleState } from "../lib/liveState";
import type { ReplaySession } from "./ReplayPanel";
import { DownloadStatus, useDownload } from "./useDownload";

interface Props {
  siteId: number;
  /** The site's vehicles. */
  vehicles: VehicleState[];
  /** The vehicle selected in the list: the export's vehicle until another is picked here. */
  selected: VehicleState | null;
  replay: ReplaySession | null;
  /** The selected vehicle's history window (the details' history table), seconds. */
  historyS: number;
  /** The trails' window (every vehicle's on the plan), seconds. */
  trailS: number;
}

/** The range inputs as edited for one choice of vehicle ("" for all); other choices show their own range. */
interface Edited {
  vehicle: string;
  from: string;
  to: string;
}

export function PositionsExport({ siteId, vehicles, selected, replay, historyS, trailS }: Props) {
  const [format, setFormat] = useState<PositionFormat>("csv");
  const [choice, setChoice] = useState<string | null>(null); // null: the selected vehicle; "": every vehicle
  const [edited, setEdited] = useState<Edited | null>(null);
  const download = useDownload();

  const vehicle = vehicles.find((v) => v.name === (choice ?? selected?.name)) ?? null;
  const name = vehicle?.name ?? "";
  const times = vehicles.flatMap((v) => (v.position ? [v.position.t] : []));
  const latestT = vehicle ? (vehicle.position?.t ?? null) : times.length > 0 ? Math.max(...times) : null;
  const replayed = vehicle && replay?.vehicleId === vehicle.id ? replay.clock : null;
  const shown = shownRange(
    { latestT, replay: replayed ? [replayed.start, replayed.end] : null },
    vehicle ? historyS : trailS,
  );
  const [from, to] = edited?.vehicle === name ? [edited.from, edited.to] : shown;
  const edit = (range: { from?: string; to?: string }) => setEdited({ vehicle: name, from, to, ...range });

  const start = () => {
    const range = rangeQuery(from, to, latestT ?? Date.now() / 1000);
    if ("error" in range) {
      download.fail(range.error);
      return;
    }
    const query = { format, vehicle: vehicle ? name : null, since: range.since, until: range.until };
    const url = buildUrl("/api/sites/{site_id}/positions/export", { site_id: siteId }, query);
    void download.run(url, `positions${vehicle ? `-${name}` : ""}.${format}`);
  };

  return (
    <section className="export-box" data-testid="positions-export">
      <h3>Export positions</h3>
      <div className="row">
        <select
          data-testid="positions-export-vehicle"
          value={name}
          onChange={(e) => {
            setChoice(e.target.value);
            setEdited(null);
          }}
          title="One vehicle's history or every vehicle's (TUM holds one)"
        >
          <option value="">all vehicles</option>
          {vehicles.map((v) => (
            <option key={v.id} value={v.name}>
              {v.name}
            </option>
          ))}
        </select>
        <select
          data-testid="positions-export-format"
          value={format}
          onChange={(e) => setFormat(e.target.value as PositionFormat)}
          title="File format (docs/formats.md, Exports)"
        >
          {Object.entries(POSITION_FORMATS).map(([value, label]) => (
            <option key={value} value={value}>
              {label}
            </option>
          ))}
        </select>
      </div>
      <div className="row" title="Frame times on the vehicle's clock; an empty end is open">
        <label>
          From{" "}
          <input
            data-testid="positions-export-from"
            value={from}
            onChange={(e) => edit({ from: e.target.value })}
            placeholder="the start"
            size={17}
          />
        </label>
        <label>
          To{" "}
          <input
            data-testid="positions-export-to"
            value={to}
            onChange={(e) => edit({ to: e.target.value })}
            placeholder="the latest"
            size={17}
          />
        </label>
        {edited?.vehicle === name && (
          <button data-testid="positions-export-shown" onClick={() => setEdited(null)} title="The range shown">
            ⟲
          </button>
        )}
        <span className="spacer" />
        <button data-testid="positions-export-download" onClick={start} disabled={download.busy}>
          {download.busy ? "Exporting…" : "Download"}
        </button>
      </div>
      <DownloadStatus download={download} testId="positions-export" />
    </section>
  );
}

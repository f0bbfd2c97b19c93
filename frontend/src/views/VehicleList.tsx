// The monitoring view's list of the site's vehicles: name (with the vehicle's own colour, as its trail and name
// on the plan, and the appearance-only badge under it), status, confidence, position (easting over northing, one column), and how
// long ago the server last heard from it: narrow enough for the side panel at 1366 px with mine-grid numbers.
import { statusOf, type VehicleState } from "../lib/liveState";
import { bandCss, confidenceBand, type ConfidenceBand } from "../lib/confidence";
import { ageOf, formatAge, formatTime } from "../lib/time";
import { useNow } from "../lib/useNow";
import { vehicleCss } from "../lib/vehicleColours";
import { AppearanceOnlyBadge, Confidence } from "./VehicleDetails";

const TICK_MS = 1000; // "last seen" counts up this often between messages

/** A band's swatch: a filled dot, a ring for lost (as on the map). */
export function BandDot({ band }: { band: ConfidenceBand }) {
  const lost = band === "lost";
  const style = lost ? { borderColor: bandCss(band) } : { background: bandCss(band) };
  return <span className={lost ? "dot ring" : "dot"} style={style} />;
}

/** A vehicle's own colour (its trail and name on the plan): a small square, unlike the bands' round dots. */
export function VehicleSwatch({ id }: { id: number }) {
  const colour = vehicleCss(id);
  return (
    <span
      className="swatch"
      style={{ background: colour }}
      data-testid="vehicle-colour"
      data-colour={colour}
      title="This vehicle's colour on the plan"
    />
  );
}

interface Props {
  vehicles: VehicleState[];
  selectedId: number | null;
  onSelect: (id: number) => void;
}

export function VehicleList({ vehicles, selectedId, onSelect }: Props) {
  const now = useNow(TICK_MS);
  return (
    <>
      <table className="vehicle-list" data-testid="vehicle-list">
        <thead>
          <tr>
            <th>Name</th>
            <th>Status</th>
            <th className="num">Conf.</th>
            <th className="num" title="Easting over northing, metres">
              E / N
            </th>
            <th className="num" title="Time since the server received the vehicle's last position">
              Last seen
            </th>
          </tr>
        </thead>
        <tbody>
          {vehicles.map((v) => (
            <VehicleRow key={v.id} v={v} now={now} selected={v.id === selectedId} onClick={() => onSelect(v.id)} />
          ))}
        </tbody>
      </table>
      {vehicles.length === 0 && <p className="muted">No vehicles on this site.</p>}
    </>
  );
}

interface RowProps {
  v: VehicleState;
  now: number;
  selected: boolean;
  onClick: () => void;
}

function VehicleRow({ v, now, selected, onClick }: RowProps) {
  const status = statusOf(v);
  const p = v.position;
  const band = p ? confidenceBand(p.confidence, p.lost, v.stale) : "stale";
  const age = p ? ageOf(p.received_at, now) : null;
  return (
    <tr
      className={selected ? "selected" : ""}
      onClick={onClick}
      data-testid={`vehicle-row-${v.name}`}
      data-status={status}
      data-band={band}
      data-seq={p?.seq ?? ""}
      data-trail={v.trail.length}
    >
      <td className="name">
        <VehicleSwatch id={v.id} />
        {v.name}
        {p && <AppearanceOnlyBadge odometry={p.odometry} />}
      </td>
      <td className="wrap">
        <span
          className={`status ${status.replace(" ", "-")}`}
          style={status === "camera obscured" ? { color: "var(--fair)" } : undefined}
        >
          {status}
        </span>
      </td>
      <td className="num">{p ? <Confidence value={p.confidence} lost={p.lost} stale={v.stale} /> : "—"}</td>
      <td className="num" data-testid="position">
        {p ? (
          <>
            <div>{p.x.toFixed(1)}</div>
            <div>{p.y.toFixed(1)}</div>
          </>
        ) : (
          "—"
        )}
      </td>
      <td
        className="num"
        data-testid="last-seen"
        data-age-s={age === null ? "" : Math.max(0, Math.floor(age))}
        title={p ? `Last position received ${formatTime(p.received_at)}` : "No position yet"}
      >
        {formatAge(age)}
      </td>
    </tr>
  );
}

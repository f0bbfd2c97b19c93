// Admin: users (AdminUsers), vehicles (a new vehicle's token is shown once, with a copy button; when each was
// last seen; delete after a confirmation), sites, and uploads of plans and drives (Uploads).
// The add forms sit above their tables, so a new row never moves a button under the pointer.
import { useCallback, useEffect, useState, type FormEvent } from "react";
import { AdminUsers } from "./AdminUsers";
import { ConfirmDialog } from "./Dialog";
import { useErrors } from "./useErrors";
import { Uploads } from "./Uploads";
import { ageOf, formatAge, formatTime } from "../lib/time";
import { useNow } from "../lib/useNow";
import { apiDelete, apiGet, apiPost, type Schemas } from "../api/client";

export function AdminView({
  sites,
  onSitesChanged,
  meId,
}: {
  sites: Schemas["SiteRead"][];
  onSitesChanged: () => Promise<void>;
  /** The admin looking (who may not delete or disable themself). */
  meId: number | null;
}) {
  return (
    <div className="adminpage">
      <AdminUsers meId={meId} />
      <Vehicles sites={sites} />
      <Sites sites={sites} onChanged={onSitesChanged} />
      <Uploads sites={sites} />
    </div>
  );
}

function Vehicles({ sites }: { sites: Schemas["SiteRead"][] }) {
  const [vehicles, setVehicles] = useState<Schemas["VehicleRead"][]>([]);
  const [name, setName] = useState("");
  const [siteId, setSiteId] = useState<number | null>(null);
  const [token, setToken] = useState<{ name: string; token: string } | null>(null);
  const [deleting, setDeleting] = useState<Schemas["VehicleRead"] | null>(null);
  const [seen, setSeen] = useState<Map<number, string>>(new Map());
  const [copied, setCopied] = useState<string | null>(null);
  const [error, run] = useErrors();
  const now = useNow(5000);
  const load = useCallback(async () => {
    const [list, latest] = await Promise.all([apiGet("/api/vehicles"), apiGet("/api/positions/latest")]);
    setVehicles(list);
    setSeen(new Map(latest.flatMap((l) => (l.position ? [[l.vehicle_id, l.position.received_at] as const] : []))));
  }, []);
  const copy = (text: string) =>
    void navigator.clipboard.writeText(text).then(
      () => setCopied("copied"),
      () => setCopied("could not copy: select the token and copy it by hand"),
    );
  useEffect(() => void run(load), [run, load]);
  const site = siteId ?? sites[0]?.id ?? null;
  const siteName = (id: number) => sites.find((s) => s.id === id)?.name ?? String(id);
  const create = (e: FormEvent) => {
    e.preventDefault();
    if (site === null) return;
    void run(async () => {
      const v = await apiPost("/api/vehicles", {}, { name, site_id: site });
      setToken({ name: v.name, token: v.token });
      setCopied(null);
      setName("");
      await load();
    });
  };
  const rotate = (id: number, vehicleName: string) =>
    void run(async () => {
      const v = await apiPost("/api/vehicles/{vehicle_id}/token", { vehicle_id: id });
      setToken({ name: vehicleName, token: v.token });
      setCopied(null);
    });
  return (
    <section className="card" data-testid="admin-vehicles">
      <h2>Vehicles</h2>
      <form className="row" onSubmit={create}>
        <input
          placeholder="vehicle name"
          value={name}
          onChange={(e) => setName(e.target.value)}
          data-testid="new-vehicle-name"
        />
        <select value={site ?? ""} onChange={(e) => setSiteId(Number(e.target.value))}>
          {sites.map((s) => (
            <option key={s.id} value={s.id}>
              {s.name}
            </option>
          ))}
        </select>
        <button className="primary" type="submit" disabled={!name || site === null}>
          Add vehicle
        </button>
      </form>
      <table>
        <thead>
          <tr>
            <th>Name</th>
            <th>Site</th>
            <th>Last seen</th>
            <th />
          </tr>
        </thead>
        <tbody>
          {vehicles.map((v) => (
            <tr key={v.id} data-testid={`admin-vehicle-${v.name}`}>
              <td>{v.name}</td>
              <td>{siteName(v.site_id)}</td>
              <LastSeen at={seen.get(v.id) ?? null} now={now} name={v.name} />
              <td className="row" style={{ margin: 0 }}>
                <button onClick={() => rotate(v.id, v.name)}>New token</button>
                <button className="danger" data-testid={`vehicle-delete-${v.name}`} onClick={() => setDeleting(v)}>
                  Delete
                </button>
              </td>
            </tr>
          ))}
        </tbody>
      </table>
      {token && (
        <div data-testid="vehicle-token">
          <p>
            Token for <b>{token.name}</b> — copy it now, it is not shown again:
          </p>
          <div className="token">{token.token}</div>
          <div className="row">
            <button className="primary" data-testid="copy-token" onClick={() => copy(token.token)}>
              Copy token
            </button>
            {copied && (
              <span className="muted" data-testid="copy-token-state">
                {copied}
              </span>
            )}
            <span className="spacer" />
            <button onClick={() => setToken(null)}>Done</button>
          </div>
        </div>
      )}
      {error && <p className="error">{error}</p>}
      {deleting && (
        <ConfirmDialog
          title={`Delete vehicle ${deleting.name}?`}
          confirmLabel="Delete"
          danger
          onCancel={() => setDeleting(null)}
          onConfirm={() => {
            const gone = deleting;
            setDeleting(null);
            void run(async () => {
              await apiDelete("/api/vehicles/{vehicle_id}", { vehicle_id: gone.id });
              await load();
            });
          }}
        >
          <p>
            {deleting.name} ({siteName(deleting.site_id)}) and its positions are removed, and its token stops working.
            This cannot be undone.
          </p>
        </ConfirmDialog>
      )}
    </section>
  );
}

/** When a vehicle's last position arrived: its age, the clock time in the title. */
function LastSeen({ at, now, name }: { at: string | null; now: number; name: string }) {
  return (
    <td data-testid={`admin-last-seen-${name}`} title={at ? `Last position received ${formatTime(at)}` : "Never seen"}>
      {at ? `${formatAge(ageOf(at, now))} ago` : "never"}
    </td>
  );
}

function Sites({ sites, onChanged }: { sites: Schemas["SiteRead"][]; onChanged: () => Promise<void> }) {
  const [name, setName] = useState("");
  const [description, setDescription] = useState("");
  const [error, run] = useErrors();
  const create = (e: FormEvent) => {
    e.preventDefault();
    void run(async () => {
      await apiPost("/api/sites", {}, { name, description });
      setName("");
      setDescription("");
      await onChanged();
    });
  };
  return (
    <section className="card" data-testid="admin-sites">
      <h2>Sites</h2>
      <table>
        <thead>
          <tr>
            <th>Name</th>
            <th>Description</th>
            <th>Created</th>
          </tr>
        </thead>
        <tbody>
          {sites.map((s) => (
            <tr key={s.id} data-testid={`site-row-${s.name}`}>
              <td>{s.name}</td>
              <td>{s.description}</td>
              <td>{formatTime(s.created_at)}</td>
            </tr>
          ))}
        </tbody>
      </table>
      <form className="row" onSubmit={create}>
        <input
          placeholder="site name"
          value={name}
          onChange={(e) => setName(e.target.value)}
          data-testid="new-site-name"
        />
        <input placeholder="description" value={description} onChange={(e) => setDescription(e.target.value)} />
        <button className="primary" type="submit" disabled={!name}>
          Add site
        </button>
      </form>
      {error && <p className="error">{error}</p>}
    </section>
  );
}

// Admin: users and roles, vehicles (a new vehicle's token is shown once), sites.
import { useCallback, useEffect, useState, type FormEvent } from "react";
import { formatTime } from "../lib/time";
import { ApiError, apiDelete, apiGet, apiPatch, apiPost, type Schemas } from "../api/client";

type Role = Schemas["Role"];

function useErrors(): [string | null, (f: () => Promise<void>) => Promise<void>] {
  const [error, setError] = useState<string | null>(null);
  const run = useCallback(async (f: () => Promise<void>) => {
    setError(null);
    try {
      await f();
    } catch (e) {
      setError(e instanceof ApiError ? e.message : String(e));
    }
  }, []);
  return [error, run];
}

export function AdminView({
  sites,
  onSitesChanged,
}: {
  sites: Schemas["SiteRead"][];
  onSitesChanged: () => Promise<void>;
}) {
  return (
    <div className="adminpage">
      <Users />
      <Vehicles sites={sites} />
      <Sites sites={sites} onChanged={onSitesChanged} />
    </div>
  );
}

function Users() {
  const [users, setUsers] = useState<Schemas["UserRead"][]>([]);
  const [name, setName] = useState("");
  const [password, setPassword] = useState("");
  const [role, setRole] = useState<Role>("viewer");
  const [error, run] = useErrors();
  const load = useCallback(async () => setUsers(await apiGet("/api/users")), []);
  useEffect(() => void run(load), [run, load]);
  const create = (e: FormEvent) => {
    e.preventDefault();
    void run(async () => {
      await apiPost("/api/users", {}, { username: name, password, role });
      setName("");
      setPassword("");
      await load();
    });
  };
  return (
    <section className="card" data-testid="admin-users">
      <h2>Users</h2>
      <table>
        <thead>
          <tr>
            <th>Name</th>
            <th>Role</th>
            <th>Status</th>
            <th />
          </tr>
        </thead>
        <tbody>
          {users.map((u) => (
            <tr key={u.id} data-testid={`user-row-${u.username}`}>
              <td>{u.username}</td>
              <td>{u.role}</td>
              <td>{u.disabled_at ? "disabled" : "active"}</td>
              <td>
                <button
                  data-testid={`user-toggle-${u.username}`}
                  title="Disabling logs the user out everywhere"
                  onClick={() =>
                    void run(async () => {
                      await apiPatch("/api/users/{user_id}", { user_id: u.id }, { disabled: !u.disabled_at });
                      await load();
                    })
                  }
                >
                  {u.disabled_at ? "Enable" : "Disable"}
                </button>{" "}
                <button
                  className="danger"
                  onClick={() =>
                    void run(async () => {
                      await apiDelete("/api/users/{user_id}", { user_id: u.id });
                      await load();
                    })
                  }
                >
                  Delete
                </button>
              </td>
            </tr>
          ))}
        </tbody>
      </table>
      <form className="row" onSubmit={create}>
        <input
          placeholder="user name"
          value={name}
          onChange={(e) => setName(e.target.value)}
          data-testid="new-user-name"
        />
        <input
          placeholder="password (8+)"
          type="password"
          value={password}
          onChange={(e) => setPassword(e.target.value)}
          data-testid="new-user-password"
        />
        <select value={role} onChange={(e) => setRole(e.target.value as Role)} data-testid="new-user-role">
          <option value="viewer">viewer</option>
          <option value="surveyor">surveyor</option>
          <option value="admin">admin</option>
        </select>
        <button className="primary" type="submit" disabled={!name || !password}>
          Add user
        </button>
      </form>
      {error && <p className="error">{error}</p>}
    </section>
  );
}

function Vehicles({ sites }: { sites: Schemas["SiteRead"][] }) {
  const [vehicles, setVehicles] = useState<Schemas["VehicleRead"][]>([]);
  const [name, setName] = useState("");
  const [siteId, setSiteId] = useState<number | null>(null);
  const [token, setToken] = useState<{ name: string; token: string } | null>(null);
  const [error, run] = useErrors();
  const load = useCallback(async () => setVehicles(await apiGet("/api/vehicles")), []);
  useEffect(() => void run(load), [run, load]);
  const site = siteId ?? sites[0]?.id ?? null;
  const siteName = (id: number) => sites.find((s) => s.id === id)?.name ?? String(id);
  const create = (e: FormEvent) => {
    e.preventDefault();
    if (site === null) return;
    void run(async () => {
      const v = await apiPost("/api/vehicles", {}, { name, site_id: site });
      setToken({ name: v.name, token: v.token });
      setName("");
      await load();
    });
  };
  const rotate = (id: number, vehicleName: string) =>
    void run(async () => {
      const v = await apiPost("/api/vehicles/{vehicle_id}/token", { vehicle_id: id });
      setToken({ name: vehicleName, token: v.token });
    });
  return (
    <section className="card" data-testid="admin-vehicles">
      <h2>Vehicles</h2>
      <table>
        <thead>
          <tr>
            <th>Name</th>
            <th>Site</th>
            <th />
          </tr>
        </thead>
        <tbody>
          {vehicles.map((v) => (
            <tr key={v.id} data-testid={`admin-vehicle-${v.name}`}>
              <td>{v.name}</td>
              <td>{siteName(v.site_id)}</td>
              <td className="row" style={{ margin: 0 }}>
                <button onClick={() => rotate(v.id, v.name)}>New token</button>
                <button
                  className="danger"
                  onClick={() =>
                    void run(async () => {
                      await apiDelete("/api/vehicles/{vehicle_id}", { vehicle_id: v.id });
                      await load();
                    })
                  }
                >
                  Delete
                </button>
              </td>
            </tr>
          ))}
        </tbody>
      </table>
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
      {token && (
        <div data-testid="vehicle-token">
          <p>
            Token for <b>{token.name}</b> — copy it now, it is not shown again:
          </p>
          <div className="token">{token.token}</div>
          <button onClick={() => setToken(null)}>Done</button>
        </div>
      )}
      {error && <p className="error">{error}</p>}
    </section>
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

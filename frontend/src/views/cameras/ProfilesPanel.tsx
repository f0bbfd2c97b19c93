// Camera profiles: the stored ones (select, delete after a confirmation), the fitted camera saved as a new
// profile or into the selected one, and the selected profile given to a vehicle (a copy of its block).
import { useCallback, useEffect, useState } from "react";
import { assignProfile, putProfile } from "../../api/cameras";
import { apiDelete, apiGet, apiPost, type Schemas } from "../../api/client";
import { ConfirmDialog } from "../Dialog";
import { useErrors } from "../useErrors";

type Profile = Schemas["CameraProfileRead"];

interface Props {
  /** The camera block of the current fit; null until the ground has been fitted to the current points. */
  block: Schemas["VehicleCamera"] | null;
}

export function ProfilesPanel({ block }: Props) {
  const [profiles, setProfiles] = useState<Profile[]>([]);
  const [vehicles, setVehicles] = useState<Schemas["VehicleRead"][]>([]);
  const [selected, setSelected] = useState<number | null>(null);
  const [name, setName] = useState("");
  const [description, setDescription] = useState("");
  const [vehicle, setVehicle] = useState<number | null>(null);
  const [deleting, setDeleting] = useState<Profile | null>(null);
  const [done, setDone] = useState<string | null>(null);
  const [error, run] = useErrors();

  const load = useCallback(async () => {
    const [page, fleet] = await Promise.all([
      apiGet("/api/camera-profiles", {}, { limit: 500 }),
      apiGet("/api/vehicles"),
    ]);
    setProfiles(page.items);
    setVehicles(fleet);
  }, []);
  useEffect(() => void run(load), [run, load]);

  const chosen = profiles.find((p) => p.id === selected) ?? null;
  const select = (p: Profile) => {
    setSelected(p.id);
    setName(p.name);
    setDescription(p.description);
  };
  const act = (f: () => Promise<string>) =>
    void run(async () => {
      setDone(null);
      setDone(await f());
    });
  const create = () =>
    act(async () => {
      if (!block) return "";
      const made = await apiPost("/api/camera-profiles", {}, { name, description, camera: block });
      await load();
      setSelected(made.id);
      return `Saved profile ${made.name}`;
    });
  const update = () =>
    act(async () => {
      if (!chosen) return "";
      const changed = await putProfile(chosen.id, { name, description, ...(block ? { camera: block } : {}) });
      await load();
      return block ? `Updated ${changed.name} with this fit` : `Renamed ${changed.name}`;
    });
  const assign = () =>
    act(async () => {
      const target = vehicles.find((v) => v.id === vehicle);
      if (!chosen || !target) return "";
      await assignProfile(target.id, chosen.id);
      await load();
      return `${target.name} now has the camera of ${chosen.name}`;
    });

  return (
    <section data-testid="camera-profiles">
      <h3>Camera profiles</h3>
      <table>
        <thead>
          <tr>
            <th>Name</th>
            <th className="num">size</th>
            <th className="num">k_x</th>
            <th>lens</th>
            <th />
          </tr>
        </thead>
        <tbody className="picklist">
          {profiles.map((p) => (
            <tr
              key={p.id}
              className={p.id === selected ? "selected" : ""}
              data-testid={`camera-profile-${p.name}`}
              title={p.description}
            >
              <td onClick={() => select(p)}>{p.name}</td>
              <td className="num" onClick={() => select(p)}>
                {p.camera.width}x{p.camera.height}
              </td>
              <td className="num" onClick={() => select(p)}>
                {p.camera.k_x.toFixed(4)}
              </td>
              <td onClick={() => select(p)}>{p.camera.lens?.model ?? "none"}</td>
              <td>
                <button
                  className="danger"
                  data-testid={`camera-profile-delete-${p.name}`}
                  onClick={() => setDeleting(p)}
                >
                  Delete
                </button>
              </td>
            </tr>
          ))}
        </tbody>
      </table>
      {profiles.length === 0 && <p className="muted">No profiles yet.</p>}
      <div className="row">
        <input
          placeholder="profile name"
          value={name}
          onChange={(e) => setName(e.target.value)}
          data-testid="camera-profile-name"
        />
        <input placeholder="description" value={description} onChange={(e) => setDescription(e.target.value)} />
      </div>
      <div className="row">
        <button
          className="primary"
          disabled={!block || !name}
          title={block ? "Store this camera under the name" : "Fit the ground first"}
          onClick={create}
          data-testid="camera-profile-create"
        >
          Save as new
        </button>
        <button disabled={!chosen || !name} onClick={update} data-testid="camera-profile-update">
          {block ? "Update selected" : "Rename selected"}
        </button>
      </div>
      <div className="row">
        <select
          value={vehicle ?? ""}
          onChange={(e) => setVehicle(e.target.value ? Number(e.target.value) : null)}
          data-testid="camera-vehicle"
        >
          <option value="">vehicle…</option>
          {vehicles.map((v) => (
            <option key={v.id} value={v.id}>
              {v.name}
              {v.has_camera ? " (has a camera)" : ""}
            </option>
          ))}
        </select>
        <button disabled={!chosen || vehicle === null} onClick={assign} data-testid="camera-assign">
          Give {chosen ? chosen.name : "the selected profile"}
        </button>
      </div>
      {done && (
        <div className="ok" data-testid="camera-profiles-done">
          {done}
        </div>
      )}
      {error && (
        <div className="error" role="alert" data-testid="camera-profiles-error">
          {error}
        </div>
      )}
      {deleting && (
        <ConfirmDialog
          title={`Delete camera profile ${deleting.name}?`}
          confirmLabel="Delete"
          danger
          onCancel={() => setDeleting(null)}
          onConfirm={() => {
            const gone = deleting;
            setDeleting(null);
            act(async () => {
              await apiDelete("/api/camera-profiles/{profile_id}", { profile_id: gone.id });
              if (selected === gone.id) setSelected(null);
              await load();
              return `Deleted ${gone.name}`;
            });
          }}
        >
          <p>Vehicles already given {deleting.name} keep their copy of its camera. This cannot be undone.</p>
        </ConfirmDialog>
      )}
    </section>
  );
}

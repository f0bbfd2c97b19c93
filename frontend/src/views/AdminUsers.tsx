// Admin: users. Add (the form sits above the table, so a new row never moves a button under the pointer),
// change a role, reset a password, disable or enable, and delete after a confirmation. What the server refuses
// (lib/userRules.ts: yourself, the last active admin) is disabled here with the reason as its tooltip.
import { useCallback, useEffect, useState, type FormEvent } from "react";
import { apiDelete, apiGet, apiPatch, apiPost, type Schemas } from "../api/client";
import { userGuards } from "../lib/userRules";
import { formatTime } from "../lib/time";
import { ConfirmDialog, Modal } from "./Dialog";
import { useErrors } from "./useErrors";

type Role = Schemas["Role"];
type User = Schemas["UserRead"];
const ROLES: Role[] = ["viewer", "surveyor", "admin"];
const MIN_PASSWORD_LENGTH = 8;

export function AdminUsers({ meId }: { meId: number | null }) {
  const [users, setUsers] = useState<User[]>([]);
  const [name, setName] = useState("");
  const [password, setPassword] = useState("");
  const [role, setRole] = useState<Role>("viewer");
  const [deleting, setDeleting] = useState<User | null>(null);
  const [resetting, setResetting] = useState<User | null>(null);
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
  const patch = (u: User, body: Schemas["UserUpdate"]) =>
    run(async () => {
      try {
        await apiPatch("/api/users/{user_id}", { user_id: u.id }, body);
      } finally {
        await load(); // a refused change shows the stored state again
      }
    });
  return (
    <section className="card span-2" data-testid="admin-users">
      <h2>Users</h2>
      <form className="row" onSubmit={create}>
        <input
          placeholder="user name"
          value={name}
          onChange={(e) => setName(e.target.value)}
          data-testid="new-user-name"
        />
        <input
          placeholder={`password (${MIN_PASSWORD_LENGTH}+)`}
          type="password"
          value={password}
          onChange={(e) => setPassword(e.target.value)}
          data-testid="new-user-password"
        />
        <select value={role} onChange={(e) => setRole(e.target.value as Role)} data-testid="new-user-role">
          {ROLES.map((r) => (
            <option key={r} value={r}>
              {r}
            </option>
          ))}
        </select>
        <button className="primary" type="submit" disabled={!name || !password} data-testid="add-user">
          Add user
        </button>
      </form>
      {error && (
        <p className="error" role="alert" data-testid="users-error">
          {error}
        </p>
      )}
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
          {users.map((u) => {
            const guards = userGuards(u, users, meId);
            return (
              <tr key={u.id} data-testid={`user-row-${u.username}`}>
                <td title={`since ${formatTime(u.created_at)}`}>
                  {u.username}
                  {u.id === meId ? <span className="muted"> (you)</span> : null}
                </td>
                <td>
                  <select
                    value={u.role}
                    data-testid={`user-role-${u.username}`}
                    disabled={guards.demote !== null}
                    title={guards.demote ?? "Changing the role logs the user out everywhere"}
                    onChange={(e) => void patch(u, { role: e.target.value as Role })}
                  >
                    {ROLES.map((r) => (
                      <option key={r} value={r}>
                        {r}
                      </option>
                    ))}
                  </select>
                </td>
                <td>{u.disabled_at ? "disabled" : "active"}</td>
                <td className="row" style={{ margin: 0, flexWrap: "nowrap" }}>
                  <button
                    data-testid={`user-toggle-${u.username}`}
                    disabled={guards.disable !== null}
                    title={guards.disable ?? "Disabling logs the user out everywhere"}
                    onClick={() => void patch(u, { disabled: !u.disabled_at })}
                  >
                    {u.disabled_at ? "Enable" : "Disable"}
                  </button>
                  <button data-testid={`user-reset-${u.username}`} onClick={() => setResetting(u)}>
                    Reset password
                  </button>
                  <button
                    className="danger"
                    data-testid={`user-delete-${u.username}`}
                    disabled={guards.delete !== null}
                    title={guards.delete ?? `Delete ${u.username}`}
                    onClick={() => setDeleting(u)}
                  >
                    Delete
                  </button>
                </td>
              </tr>
            );
          })}
        </tbody>
      </table>
      {deleting && (
        <ConfirmDialog
          title={`Delete user ${deleting.username}?`}
          confirmLabel="Delete"
          danger
          onCancel={() => setDeleting(null)}
          onConfirm={() => {
            const u = deleting;
            setDeleting(null);
            void run(async () => {
              await apiDelete("/api/users/{user_id}", { user_id: u.id });
              await load();
            });
          }}
        >
          <p>
            {deleting.username} ({deleting.role}) can no longer log in, and their tokens stop working. This cannot be
            undone; <b>Disable</b> keeps the account.
          </p>
        </ConfirmDialog>
      )}
      {resetting && (
        <ResetPassword
          user={resetting}
          onClose={() => setResetting(null)}
          onReset={(newPassword) => {
            const u = resetting;
            setResetting(null);
            void patch(u, { password: newPassword });
          }}
        />
      )}
    </section>
  );
}

function ResetPassword({
  user,
  onClose,
  onReset,
}: {
  user: User;
  onClose: () => void;
  onReset: (password: string) => void;
}) {
  const [password, setPassword] = useState("");
  const short = password.length < MIN_PASSWORD_LENGTH;
  return (
    <Modal title={`New password for ${user.username}`} onClose={onClose} testId="reset-dialog">
      <form
        onSubmit={(e) => {
          e.preventDefault();
          if (!short) onReset(password);
        }}
      >
        <p className="muted">The user is logged out everywhere and logs in again with this password.</p>
        <input
          type="password"
          autoFocus
          placeholder={`new password (${MIN_PASSWORD_LENGTH}+)`}
          value={password}
          onChange={(e) => setPassword(e.target.value)}
          data-testid="reset-password"
        />
        <div className="row">
          <span className="spacer" />
          <button type="button" onClick={onClose}>
            Cancel
          </button>
          <button className="primary" type="submit" disabled={short} data-testid="reset-ok">
            Set password
          </button>
        </div>
      </form>
    </Modal>
  );
}

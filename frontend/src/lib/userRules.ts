// What an admin may do to a user, as the server enforces it (services/users.py), so the UI can disable a button
// and say why instead of waiting for a 409: nobody deletes or disables themself, and the last active admin is
// never deleted, demoted or disabled (the server could not be administered any more).

export interface UserLike {
  id: number;
  username: string;
  role: string;
  disabled_at?: string | null;
}

/** Why each change is refused for ``user`` (null: allowed), with ``meId`` the admin looking. */
export interface UserGuards {
  delete: string | null;
  demote: string | null;
  disable: string | null;
}

export function userGuards(user: UserLike, users: readonly UserLike[], meId: number | null): UserGuards {
  const activeAdmin = (u: UserLike) => u.role === "admin" && !u.disabled_at;
  const lastAdmin =
    activeAdmin(user) && !users.some((u) => u.id !== user.id && activeAdmin(u))
      ? `${user.username} is the last active admin; make another user admin first`
      : null;
  const self = user.id === meId;
  return {
    delete: self ? "you cannot delete your own account" : lastAdmin,
    demote: lastAdmin,
    disable: user.disabled_at ? null : self ? "you cannot disable your own account" : lastAdmin,
  };
}

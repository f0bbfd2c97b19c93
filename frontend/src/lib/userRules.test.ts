import { describe, expect, it } from "vitest";
import { userGuards, type UserLike } from "./userRules";

const boss: UserLike = { id: 1, username: "boss", role: "admin" };
const deputy: UserLike = { id: 2, username: "deputy", role: "admin" };
const viewer: UserLike = { id: 3, username: "viewer", role: "viewer" };

describe("userGuards", () => {
  it("keeps the last active admin: no delete, demote or disable", () => {
    const guards = userGuards(boss, [boss, viewer], 99);
    expect(guards.delete).toBe("boss is the last active admin; make another user admin first");
    expect(guards.demote).toBe(guards.delete);
    expect(guards.disable).toBe(guards.delete);
  });

  it("refuses deleting or disabling yourself, even with another admin", () => {
    const guards = userGuards(boss, [boss, deputy], boss.id);
    expect(guards.delete).toBe("you cannot delete your own account");
    expect(guards.disable).toBe("you cannot disable your own account");
    expect(guards.demote).toBeNull(); // another admin remains
  });

  it("does not count a disabled admin, and lets a disabled admin be enabled or deleted", () => {
    const dormant = { ...deputy, disabled_at: "2026-12-01T00:00:00Z" };
    expect(userGuards(boss, [boss, dormant], 99).delete).toContain("last active admin");
    expect(userGuards(dormant, [boss, dormant], boss.id)).toEqual({ delete: null, demote: null, disable: null });
  });

  it("allows everything on other users", () => {
    expect(userGuards(viewer, [boss, viewer], boss.id)).toEqual({ delete: null, demote: null, disable: null });
  });
});

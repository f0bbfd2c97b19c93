import { describe as group, expect, it } from "vitest";
import { EMPTY_HISTORY, describe, inverse, recorded, step, type GroundingEdit } from "./groundingEdits";

const created: GroundingEdit = { kind: "create", driveId: 2, frame: 40, at: { x: 10, y: 20 } };
const moved: GroundingEdit = { kind: "move", driveId: 2, frame: 40, from: { x: 10, y: 20 }, to: { x: 12.5, y: 19 } };

group("grounding edits", () => {
  it("inverts each kind of edit, and inverting twice gives the edit back", () => {
    expect(inverse(created)).toEqual({ ...created, kind: "delete" });
    expect(inverse(moved)).toEqual({
      kind: "move",
      driveId: 2,
      frame: 40,
      from: { x: 12.5, y: 19 },
      to: { x: 10, y: 20 },
    });
    for (const e of [created, moved, inverse(created)]) expect(inverse(inverse(e))).toEqual(e);
  });

  it("undoing a delete re-creates the grounding with its station and enabled flag", () => {
    const deleted: GroundingEdit = { ...created, kind: "delete", station: "STN-104", enabled: false };
    expect(inverse(deleted)).toEqual({ ...created, station: "STN-104", enabled: false });
  });

  it("undoes the newest edit first, redoes it, and a new edit clears redo", () => {
    let h = recorded(recorded(EMPTY_HISTORY, created), moved);
    const u1 = step(h, "undo")!;
    expect(u1.apply).toEqual(inverse(moved));
    h = u1.next;
    const u2 = step(h, "undo")!;
    expect(u2.apply).toEqual(inverse(created));
    h = u2.next;
    expect(h).toEqual({ undo: [], redo: [moved, created] });
    expect(step(h, "undo")).toBeNull();
    const r1 = step(h, "redo")!;
    expect(r1.apply).toEqual(created);
    expect(r1.next).toEqual({ undo: [created], redo: [moved] });
    expect(recorded(r1.next, moved)).toEqual({ undo: [created, moved], redo: [] });
  });

  it("describes edits for the status line", () => {
    expect(describe(moved, "east")).toBe("moved the grounding of east frame 40 to E 12.50 N 19.00");
    expect(describe(inverse(created), "east")).toBe("removed the grounding of east frame 40");
    expect(describe({ ...created, at: { x: 1, y: 2 }, station: "STN-104" }, "east")).toBe(
      "grounded east frame 40 at station STN-104, E 1.00 N 2.00",
    );
  });
});

// The grounding workstation's edits through the API (create, delete, move), each recorded for undo and redo
// (see lib/groundingEdits.ts). Edits name groundings by (drive, frame); the id is looked up when one is applied.
import { useRef, useState } from "react";
import { useLatest } from "../lib/useLatest";
import { ApiError, apiDelete, apiPatch, apiPost, type Schemas } from "../api/client";
import { EMPTY_HISTORY, describe, recorded, step, type EditHistory, type GroundingEdit } from "../lib/groundingEdits";

type Grounding = Schemas["GroundingRead"];

interface Options {
  /** The site's groundings as last loaded. */
  groundings: Grounding[];
  /** Reload the groundings after an edit. */
  reload: () => Promise<void>;
  /** Show a line of status (what was done, or the API's error). */
  say: (message: string) => void;
}

export function useGroundingEdits({ groundings, reload, say }: Options) {
  const [history, setHistory] = useState<EditHistory>(EMPTY_HISTORY);
  const current = useLatest(groundings);
  const busy = useRef(false);

  const find = (driveId: number, frame: number): Grounding => {
    const g = current.current.find((r) => r.drive_id === driveId && r.frame === frame);
    if (!g) throw new ApiError(404, `frame ${frame} of drive ${driveId} has no grounding any more`);
    return g;
  };
  const nameOf = (driveId: number) => current.current.find((g) => g.drive_id === driveId)?.drive ?? `drive ${driveId}`;

  const apply = async (edit: GroundingEdit): Promise<void> => {
    if (edit.kind === "create") {
      const { driveId, frame, at } = edit;
      await apiPost(
        "/api/drives/{drive_id}/groundings",
        { drive_id: driveId },
        { frame, x: at.x, y: at.y, station: edit.station ?? null, enabled: edit.enabled ?? true },
      );
    } else if (edit.kind === "delete") {
      await apiDelete("/api/groundings/{grounding_id}", { grounding_id: find(edit.driveId, edit.frame).id });
    } else {
      const id = find(edit.driveId, edit.frame).id;
      await apiPatch("/api/groundings/{grounding_id}", { grounding_id: id }, { x: edit.to.x, y: edit.to.y });
    }
  };

  /** Reload the groundings, then accept the next edit and say what happened (so the message means "done"). */
  const settle = async (said: string) => {
    try {
      await reload();
    } finally {
      busy.current = false;
      say(said);
    }
  };

  /** Apply a new edit; on success it can be undone. Returns whether it was applied. */
  const perform = async (edit: GroundingEdit, name?: string): Promise<boolean> => {
    if (busy.current) return false;
    busy.current = true;
    let said: string;
    let ok = false;
    try {
      await apply(edit);
      setHistory((h) => recorded(h, edit));
      said = describe(edit, name ?? nameOf(edit.driveId));
      ok = true;
    } catch (e) {
      said = e instanceof ApiError ? e.message : String(e);
    }
    await settle(said);
    return ok;
  };

  const replay = async (direction: "undo" | "redo") => {
    const next = step(history, direction);
    if (!next || busy.current) return;
    busy.current = true;
    let said: string;
    try {
      await apply(next.apply);
      setHistory(next.next);
      said = `${direction === "undo" ? "undone" : "redone"}: ${describe(next.apply, nameOf(next.apply.driveId))}`;
    } catch (e) {
      said = e instanceof ApiError ? e.message : String(e);
    }
    await settle(said);
  };

  const create = (driveId: number, frame: number, x: number, y: number, driveName: string, station?: string) =>
    perform({ kind: "create", driveId, frame, at: { x, y }, ...(station ? { station } : {}) }, driveName);
  const remove = (id: number) => {
    const g = current.current.find((r) => r.id === id);
    if (!g) return Promise.resolve(false);
    const marks = { station: g.station, enabled: g.enabled };
    return perform({ kind: "delete", driveId: g.drive_id, frame: g.frame, at: { x: g.x_m, y: g.y_m }, ...marks });
  };
  const move = (id: number, x: number, y: number) => {
    const g = current.current.find((r) => r.id === id);
    if (!g) return Promise.resolve(false);
    return perform({ kind: "move", driveId: g.drive_id, frame: g.frame, from: { x: g.x_m, y: g.y_m }, to: { x, y } });
  };

  return {
    canUndo: history.undo.length > 0,
    canRedo: history.redo.length > 0,
    create,
    remove,
    move,
    undo: () => replay("undo"),
    redo: () => replay("redo"),
    /** Forget the history (e.g. after a CSV import replaced a drive's groundings). */
    reset: () => setHistory(EMPTY_HISTORY),
  };
}

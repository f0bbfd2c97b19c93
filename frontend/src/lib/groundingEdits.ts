// Grounding edits as data, for undo and redo: every edit the surveyor makes (create, delete, move) is kept with
// enough to replay it or its inverse through the API. A drive frame has at most one grounding, so an edit names
// its grounding by (drive, frame), not by id: a grounding deleted and re-created by undo gets a new id.

export interface GridPoint {
  /** Easting, mine grid metres. */
  x: number;
  /** Northing, mine grid metres. */
  y: number;
}

/** A deleted grounding's survey station and whether builds used it, so that undoing the delete restores them. */
export interface ControlMarks {
  station?: string | null;
  enabled?: boolean;
}

export type GroundingEdit =
  | ({ kind: "create"; driveId: number; frame: number; at: GridPoint } & ControlMarks)
  | ({ kind: "delete"; driveId: number; frame: number; at: GridPoint } & ControlMarks)
  | { kind: "move"; driveId: number; frame: number; from: GridPoint; to: GridPoint };

/** The edit that takes the groundings back to where they were before ``edit``. */
export function inverse(edit: GroundingEdit): GroundingEdit {
  switch (edit.kind) {
    case "create":
      return { ...edit, kind: "delete" };
    case "delete":
      return { ...edit, kind: "create" };
    case "move":
      return { ...edit, from: edit.to, to: edit.from };
  }
}

/** Undo and redo stacks of performed edits (the newest last). */
export interface EditHistory {
  undo: GroundingEdit[];
  redo: GroundingEdit[];
}

export const EMPTY_HISTORY: EditHistory = { undo: [], redo: [] };

/** After a new edit: it can be undone, and nothing can be redone any more. */
export function recorded(history: EditHistory, edit: GroundingEdit): EditHistory {
  return { undo: [...history.undo, edit], redo: [] };
}

/**
 * One undo (``direction`` "undo") or redo step: the edit to apply now and the history once it has been applied,
 * or null when that stack is empty. Undo applies the inverse of the newest performed edit; redo applies again the
 * newest undone one.
 */
export function step(
  history: EditHistory,
  direction: "undo" | "redo",
): { apply: GroundingEdit; next: EditHistory } | null {
  const from = direction === "undo" ? history.undo : history.redo;
  const last = from[from.length - 1];
  if (!last) return null;
  const rest = from.slice(0, -1);
  if (direction === "undo") return { apply: inverse(last), next: { undo: rest, redo: [...history.redo, last] } };
  return { apply: last, next: { undo: [...history.undo, last], redo: rest } };
}

/** A short description of an edit for the status line. */
export function describe(edit: GroundingEdit, driveName: string): string {
  const where = (p: GridPoint) => `E ${p.x.toFixed(2)} N ${p.y.toFixed(2)}`;
  switch (edit.kind) {
    case "create":
      return `grounded ${driveName} frame ${edit.frame} at ${edit.station ? `station ${edit.station}, ` : ""}${where(edit.at)}`;
    case "delete":
      return `removed the grounding of ${driveName} frame ${edit.frame}`;
    case "move":
      return `moved the grounding of ${driveName} frame ${edit.frame} to ${where(edit.to)}`;
  }
}

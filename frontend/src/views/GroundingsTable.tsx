// The grounding workstation's table (residuals of the latest build, sortable, colour-coded; each grounding's
// station and whether builds use it) and its keyboard-shortcut help.
import type { Dispatch, SetStateAction } from "react";
import { residualClass } from "../lib/colours";
import type { GroundingRow, SortDir, SortKey } from "../lib/residuals";

type Sort = { key: SortKey; dir: SortDir };

interface Props {
  rows: GroundingRow[];
  sort: Sort;
  onSort: Dispatch<SetStateAction<Sort>>;
  editable: boolean;
  /** The selected keyframe's grounding (its row is highlighted). */
  selectedId: number | null;
  /** A row clicked: fly to its surveyed point and open its keyframe. */
  onOpen: (row: GroundingRow) => void;
  onDelete: (id: number) => void;
  /** Enable or disable a grounding for map builds. */
  onEnable: (id: number, enabled: boolean) => void;
}

export function GroundingsTable({ rows, sort, onSort, editable, selectedId, onOpen, onDelete, onEnable }: Props) {
  const header = (key: SortKey, label: string, num = true) => (
    <th
      className={`sortable ${num ? "num" : ""}`}
      data-testid={`sort-${key}`}
      onClick={() => onSort((s) => ({ key, dir: s.key === key && s.dir === "desc" ? "asc" : "desc" }))}
    >
      {label}
      {sort.key === key ? (sort.dir === "desc" ? " ▾" : " ▴") : ""}
    </th>
  );
  return (
    <table data-testid="groundings-table">
      <thead>
        <tr>
          {header("drive", "Drive", false)}
          {header("frame", "Frame")}
          <th>Station</th>
          {header("dx", "dx m")}
          {header("dy", "dy m")}
          {header("distance", "dist m")}
          <th title="Used by map builds">Use</th>
          {editable && <th />}
        </tr>
      </thead>
      <tbody>
        {rows.map((r) => (
          <tr
            key={r.id}
            className={`${r.id === selectedId ? "selected" : ""} ${r.enabled ? "" : "muted"}`}
            data-testid={`grounding-row-${r.id}`}
            data-frame={r.frame}
            data-drive={r.drive}
            onClick={() => onOpen(r)}
            title="Open this keyframe"
            style={{ cursor: "pointer" }}
          >
            <td>{r.drive}</td>
            <td className="num">{r.frame}</td>
            <td>{r.station ?? ""}</td>
            <td className="num">{r.dx === null ? "–" : r.dx.toFixed(2)}</td>
            <td className="num">{r.dy === null ? "–" : r.dy.toFixed(2)}</td>
            <td className={`num res-${residualClass(r.distance)}`}>
              {r.distance === null ? "new" : r.distance.toFixed(2)}
            </td>
            <td onClick={(e) => e.stopPropagation()}>
              <input
                type="checkbox"
                data-testid={`enable-grounding-${r.id}`}
                checked={r.enabled}
                disabled={!editable}
                title={r.enabled ? "Used by map builds" : "Left out of map builds"}
                onChange={(e) => onEnable(r.id, e.target.checked)}
              />
            </td>
            {editable && (
              <td>
                <button
                  className="danger"
                  data-testid={`delete-grounding-${r.id}`}
                  onClick={(e) => {
                    e.stopPropagation();
                    onDelete(r.id);
                  }}
                >
                  ✕
                </button>
              </td>
            )}
          </tr>
        ))}
      </tbody>
    </table>
  );
}

const SHORTCUTS: [string, string][] = [
  ["← / p", "previous keyframe"],
  ["→ / n", "next keyframe"],
  ["space", "play / pause the drive"],
  ["g / Place", "placing mode for the selected keyframe (crosshair); then click its surveyed point"],
  ["g (placing)", "ground the selected keyframe under the pointer"],
  ["Esc", "leave the placing mode"],
  ["click a white square", "select that grounding's keyframe (to move or delete it)"],
  ["x / Delete", "delete the selected keyframe's grounding"],
  ["drag a white square", "move that grounding's surveyed point"],
  ["u / Ctrl+Z", "undo"],
  ["r / Ctrl+Y", "redo"],
  ["?", "show / hide this help"],
];

export function ShortcutHelp({ editable, onClose }: { editable: boolean; onClose: () => void }) {
  return (
    <div className="help" data-testid="help-overlay" onClick={onClose}>
      <div className="card">
        <h2>Keyboard shortcuts</h2>
        <table>
          <tbody>
            {SHORTCUTS.filter(([, what]) => editable || !/ground|undo|redo|delete/.test(what)).map(([keys, what]) => (
              <tr key={keys}>
                <td>{keys}</td>
                <td>{what}</td>
              </tr>
            ))}
          </tbody>
        </table>
      </div>
    </div>
  );
}

// The selected keyframe's grounding controls: "Place" arms the placing mode (or "Move" when the keyframe is
// grounded already, which selects its grounding: move it, or delete it), the hint while placing, and the
// confirmation a doubtful point waits for; both name the survey station of a plan label the point snaps to.
import type { Schemas } from "../api/client";
import { FAR_FROM_ESTIMATE_M } from "../lib/placement";
import { ConfirmDialog } from "./Dialog";
import type { usePlacement } from "./usePlacement";

interface Props {
  placement: ReturnType<typeof usePlacement>;
  frame: number;
  /** While placing, the station of the plan label a click under the pointer would snap to. */
  stationUnder: string | null;
  grounding: Schemas["GroundingRead"] | null;
  onDelete: (id: number) => void;
}

export function PlacingPanel({ placement, frame, stationUnder, grounding, onDelete }: Props) {
  const { placing, pending } = placement;
  return (
    <section data-testid="placing" data-placing={placing ? "yes" : "no"}>
      <div className="row">
        {placing ? (
          <button data-testid="place-cancel" onClick={placement.cancel}>
            Cancel (Esc)
          </button>
        ) : (
          <button
            className="primary"
            data-testid="place-button"
            onClick={placement.begin}
            title="Then click the keyframe's surveyed point on the plan (g)"
          >
            {grounding ? "Move its point (g)" : "Place on the plan (g)"}
          </button>
        )}
        {grounding && (
          <>
            <span data-testid="selected-grounding" data-grounding={grounding.id}>
              grounded at E {grounding.x_m.toFixed(2)} N {grounding.y_m.toFixed(2)}
            </span>
            <button
              className="danger"
              data-testid="delete-selected-grounding"
              onClick={() => onDelete(grounding.id)}
              title="Delete this keyframe's grounding (x)"
            >
              Delete
            </button>
          </>
        )}
      </div>
      {placing && (
        <p className="hint" data-testid="place-hint">
          Click frame {frame}'s surveyed point on the plan (g: under the pointer; Esc cancels). A point more than{" "}
          {FAR_FROM_ESTIMATE_M} m from its current estimate or outside the walls is confirmed first.
        </p>
      )}
      {placing && stationUnder !== null && (
        <p data-testid="place-station">
          snaps to station <strong>{stationUnder}</strong>
          {grounding ? " (a move keeps the grounding's station)" : ""}
        </p>
      )}
      {pending && (
        <ConfirmDialog
          title={`${pending.target.groundingId === null ? "Ground" : "Move"} frame ${pending.target.frame} here?`}
          confirmLabel={pending.target.groundingId === null ? "Ground it here" : "Move it here"}
          onConfirm={placement.confirm}
          onCancel={placement.dismiss}
        >
          <p>
            {pending.station !== undefined && pending.target.groundingId === null && (
              <span data-testid="pending-station">station {pending.station}, </span>
            )}
            E {pending.x.toFixed(2)} N {pending.y.toFixed(2)} is:
          </p>
          <ul data-testid="placement-warnings">
            {pending.warnings.map((w) => (
              <li key={w}>{w}</li>
            ))}
          </ul>
          <p className="muted">A stray click here would pull the map out of shape.</p>
        </ConfirmDialog>
      )}
    </section>
  );
}

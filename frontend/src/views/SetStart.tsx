// Placing a selected vehicle's known start (surveyors and admins): "Set start", then a click on the plan posts
// the clicked survey point with the radius to POST /api/vehicles/{id}/start. Escape or Cancel leaves the mode;
// a click on the map outside the mode does nothing. The server's answer is shown: the start it took, or why not.
import { useCallback, useEffect, useState } from "react";
import { apiPost, ApiError } from "../api/client";
import { DEFAULT_START_RADIUS_M, describeStart, parseRadiusM, startBody } from "../lib/knownStart";
import type { PlacedStart } from "../map/StartLayer";

export type StartResult =
  { state: "sending" } | { state: "accepted"; text: string; start: PlacedStart } | { state: "refused"; text: string };

export interface SetStartControl {
  vehicleId: number | null;
  placing: boolean;
  radiusText: string;
  setRadiusText: (text: string) => void;
  result: StartResult | null;
  begin: () => void;
  cancel: () => void;
  /** A click on the map at survey ``(x, y)``: posts the start when placing, else nothing. */
  place: (x: number, y: number) => void;
}

const RADIUS_HELP = "The radius is a number of metres, 0 or more.";

/** The set-start mode of the selected vehicle (``vehicleId``); it ends when another vehicle is selected. */
export function useSetStart(vehicleId: number | null): SetStartControl {
  const [placing, setPlacing] = useState(false);
  const [radiusText, setRadiusText] = useState(String(DEFAULT_START_RADIUS_M));
  const [result, setResult] = useState<StartResult | null>(null);

  const [forVehicle, setForVehicle] = useState(vehicleId);
  if (forVehicle !== vehicleId) {
    setForVehicle(vehicleId);
    setPlacing(false);
    setResult(null);
  }

  useEffect(() => {
    if (!placing) return;
    const onKey = (e: KeyboardEvent) => {
      if (e.key === "Escape") setPlacing(false);
    };
    window.addEventListener("keydown", onKey);
    return () => window.removeEventListener("keydown", onKey);
  }, [placing]);

  const begin = useCallback(() => {
    if (parseRadiusM(radiusText) === null) {
      setResult({ state: "refused", text: RADIUS_HELP });
      return;
    }
    setResult(null);
    setPlacing(true);
  }, [radiusText]);

  const cancel = useCallback(() => setPlacing(false), []);

  const place = useCallback(
    (x: number, y: number) => {
      if (!placing || vehicleId === null) return;
      const body = startBody(x, y, radiusText);
      if (body === null) {
        setResult({ state: "refused", text: RADIUS_HELP });
        return;
      }
      setPlacing(false);
      setResult({ state: "sending" });
      apiPost("/api/vehicles/{vehicle_id}/start", { vehicle_id: vehicleId }, body)
        .then((answer) => {
          const start = { x: answer.x, y: answer.y, radius_m: answer.radius_m };
          setResult({ state: "accepted", text: describeStart(answer), start });
        })
        .catch((e: unknown) => {
          const text = e instanceof ApiError ? `Refused: ${e.message}` : `Not sent: ${String(e)}`;
          setResult({ state: "refused", text });
          setPlacing(true); // try another point; Escape leaves
        });
    },
    [placing, vehicleId, radiusText],
  );

  return { vehicleId, placing, radiusText, setRadiusText, result, begin, cancel, place };
}

/** The details panel's part: the button, the radius and the answer. */
export function SetStartPanel({ control }: { control: SetStartControl }) {
  const { placing, radiusText, setRadiusText, result, begin, cancel } = control;
  return (
    <section data-testid="set-start" data-placing={placing ? "yes" : "no"}>
      <div className="row">
        {placing ? (
          <button data-testid="set-start-cancel" onClick={cancel}>
            Cancel
          </button>
        ) : (
          <button data-testid="set-start-button" onClick={begin} disabled={result?.state === "sending"}>
            Set start
          </button>
        )}
        <label className="muted">
          radius{" "}
          <input
            data-testid="start-radius"
            value={radiusText}
            onChange={(e) => setRadiusText(e.target.value)}
            inputMode="decimal"
            size={4}
          />{" "}
          m
        </label>
      </div>
      {placing && (
        <p className="hint" data-testid="set-start-hint">
          Click the vehicle's position on the map (Esc cancels).
        </p>
      )}
      {result && (
        <p
          data-testid="start-result"
          data-state={result.state}
          className={result.state === "refused" ? "error" : result.state === "accepted" ? "ok" : "muted"}
          role={result.state === "refused" ? "alert" : "status"}
        >
          {result.state === "sending" ? "Sending…" : result.text}
        </p>
      )}
    </section>
  );
}

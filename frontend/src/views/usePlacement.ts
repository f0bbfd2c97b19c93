// The grounding workstation's placing mode: nothing on the plan is written by a plain click. "Place" (or g)
// arms it for the selected keyframe, with a crosshair; the next click (or g again, under the pointer) grounds
// the keyframe there, or moves its grounding when it has one; Escape leaves. A point far from the keyframe's
// current estimate or outside the plan's walls (lib/placement.ts) waits for a confirmation first. A point snapped
// to a plan label carries the label's text as the grounding's survey station.
import { useEffect, useState } from "react";
import { checkPlacement, type WallRings } from "../lib/placement";

export interface PlacementTarget {
  driveId: number;
  frame: number;
  /** The keyframe's grounding, when it has one (a placement moves it). */
  groundingId: number | null;
  /** The keyframe's optimised pose in the latest map version, mine-grid metres. */
  estimate: [number, number] | null;
}

export interface PendingPlacement {
  target: PlacementTarget;
  x: number;
  y: number;
  /** The survey station of the plan label the point snapped to. */
  station?: string;
  warnings: string[];
}

interface Options {
  enabled: boolean;
  target: PlacementTarget | null;
  walls: () => WallRings | null;
  /** The point a click means (snapped to the plan when snapping is on) and the station of a label it snapped to. */
  snap: (x: number, y: number) => { x: number; y: number; station?: string };
  /** Write the placement: a new grounding (named ``station`` when given), or the keyframe's grounding moved. */
  write: (target: PlacementTarget, x: number, y: number, station?: string) => Promise<unknown>;
}

export function usePlacement({ enabled, target, walls, snap, write }: Options) {
  const [placing, setPlacing] = useState(false);
  const [pending, setPending] = useState<PendingPlacement | null>(null);
  const armed = placing && enabled && target !== null;

  useEffect(() => {
    if (!armed) return;
    const onKey = (e: KeyboardEvent) => {
      if (e.key === "Escape") setPlacing(false);
    };
    window.addEventListener("keydown", onKey);
    return () => window.removeEventListener("keydown", onKey);
  }, [armed]);

  /** A click on the plan at survey (x, y): places when armed, else nothing. Returns whether it placed. */
  const place = (clickX: number, clickY: number): boolean => {
    if (!armed || target === null) return false;
    const { x, y, station } = snap(clickX, clickY);
    setPlacing(false);
    const { warnings } = checkPlacement(x, y, target.estimate, walls());
    if (warnings.length > 0) setPending({ target, x, y, station, warnings });
    else void write(target, x, y, station);
    return true;
  };

  const confirm = () => {
    if (pending === null) return;
    setPending(null);
    void write(pending.target, pending.x, pending.y, pending.station);
  };

  return {
    placing: armed,
    begin: () => enabled && target !== null && setPlacing(true),
    cancel: () => setPlacing(false),
    place,
    pending,
    confirm,
    dismiss: () => setPending(null),
  };
}

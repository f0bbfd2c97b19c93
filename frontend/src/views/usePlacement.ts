// The grounding workstation's placing mode: nothing on the plan is written by a plain click. "Place" (or g)
// arms it for the selected keyframe, with a crosshair; the next click (or g again, under the pointer) grounds
// the keyframe there, or moves its grounding when it has one; Escape leaves. A point far from the keyframe's
// current estimate or outside the plan's walls (lib/placement.ts) waits for a confirmation first.
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
  warnings: string[];
}

interface Options {
  enabled: boolean;
  target: PlacementTarget | null;
  walls: () => WallRings | null;
  /** The point a click means (snapped to the plan when snapping is on). */
  snap: (x: number, y: number) => { x: number; y: number };
  /** Write the placement: a new grounding, or the keyframe's grounding moved. */
  write: (target: PlacementTarget, x: number, y: number) => Promise<unknown>;
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
    const { x, y } = snap(clickX, clickY);
    setPlacing(false);
    const { warnings } = checkPlacement(x, y, target.estimate, walls());
    if (warnings.length > 0) setPending({ target, x, y, warnings });
    else void write(target, x, y);
    return true;
  };

  const confirm = () => {
    if (pending === null) return;
    setPending(null);
    void write(pending.target, pending.x, pending.y);
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

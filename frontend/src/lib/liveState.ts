// The monitoring view's model of the fleet, fed by /api/positions/latest and /api/live messages.

import type { Schemas } from "../api/client";

/** One stored position of a vehicle (``/api/positions/latest`` rows, the ``/api/live`` position messages). */
export type PositionMsg = Schemas["PositionRead"];

/** A vehicle with its last position and stale flag (a row of ``/api/positions/latest`` and the snapshot). */
export type VehicleRow = Schemas["VehicleLatestRead"];

/** One ``/api/live`` message: ``snapshot``, ``position`` or ``stale`` (the server's models, generated types). */
export type LiveMessage = Schemas["LiveMessage"];

export interface TrailPoint {
  x: number;
  y: number;
  t: number;
  /** The position's confidence and lost flag: the trail is drawn in confidence bands. */
  confidence: number;
  lost: boolean;
}

export interface VehicleState {
  id: number;
  name: string;
  siteId: number;
  stale: boolean;
  position: PositionMsg | null;
  /** Recent positions, oldest first, within the trail window (by frame time ``t``). */
  trail: TrailPoint[];
  /**
   * Heading, radians counter-clockwise from east: the estimate's own ``yaw`` or, without one, the direction
   * of travel over the last metres of the trail (kept while the vehicle stands); null until it has moved.
   */
  heading: number | null;
}

export type VehicleStatus = "moving" | "stopped" | "motion unknown" | "lost" | "camera obscured" | "stale" | "no fix";

/** The direction of travel is taken over at least this much of the trail, metres. */
export const HEADING_MIN_TRAVEL_M = 2;
const HEADING_LOOKBACK = 200; // trail points searched back for that distance

/** Direction of travel (radians from east) from the trail point ``minTravelM`` back to the last; null if it moved less. */
export function travelHeading(
  trail: readonly Pick<TrailPoint, "x" | "y" | "t">[],
  minTravelM = HEADING_MIN_TRAVEL_M,
): number | null {
  const last = trail[trail.length - 1];
  if (!last) return null;
  for (let i = trail.length - 2; i >= Math.max(0, trail.length - 1 - HEADING_LOOKBACK); i--) {
    const p = trail[i]!;
    if (Math.hypot(last.x - p.x, last.y - p.y) >= minTravelM) return Math.atan2(last.y - p.y, last.x - p.x);
  }
  return null;
}

/** The vehicle with its position's ``yaw`` filled from its heading when the estimate has none (for drawing). */
export function withHeading(v: VehicleState): VehicleState {
  if (!v.position || v.position.yaw !== null || v.heading === null) return v;
  return { ...v, position: { ...v.position, yaw: v.heading } };
}

/** Lost and camera obscured win over motion; motion is the server's ``moving``, never guessed. */
export function statusOf(v: VehicleState): VehicleStatus {
  if (v.stale) return "stale";
  if (v.position === null) return "no fix";
  if (v.position.lost) return "lost";
  if (v.position.obscured) return "camera obscured";
  const moving = v.position.moving;
  return moving === true ? "moving" : moving === false ? "stopped" : "motion unknown";
}

/** Whether the vehicle's camera looked obscured at its last position (a stale vehicle's too). */
export function cameraObscured(v: VehicleState): boolean {
  return v.position?.obscured === true;
}

/** What the control room is alerted to: lost vehicles, and vehicles whose camera looks obscured. */
export interface Alerts {
  lost: string[];
  obscured: { name: string; reason: string }[];
}

export function alertsOf(vehicles: readonly VehicleState[]): Alerts {
  const live = vehicles.filter((v) => !v.stale && v.position !== null);
  return {
    lost: live.filter((v) => v.position!.lost).map((v) => v.name),
    obscured: live
      .filter(cameraObscured)
      .map((v) => ({ name: v.name, reason: v.position!.obscured_reason ?? "obscured" })),
  };
}

/** Fleet state: apply snapshot/position/stale messages in order; ``lastSeq`` is what a reconnect resumes from. */
export class LiveState {
  readonly vehicles = new Map<number, VehicleState>();
  lastSeq: number | null = null;
  staleAfterS = 10;

  constructor(readonly trailWindowS = 180) {}

  apply(message: LiveMessage): void {
    switch (message.type) {
      case "snapshot": {
        this.staleAfterS = message.stale_after_s;
        const seen = new Set<number>();
        for (const row of message.vehicles) {
          seen.add(row.vehicle_id);
          const v = this.vehicle(row.vehicle_id, row.vehicle, row.site_id);
          v.stale = row.stale;
          if (row.position) this.addPosition(v, row.position);
        }
        for (const id of [...this.vehicles.keys()]) if (!seen.has(id)) this.vehicles.delete(id);
        this.lastSeq = Math.max(this.lastSeq ?? 0, message.seq);
        break;
      }
      case "position": {
        const { type: _type, ...position } = message;
        const v = this.vehicle(position.vehicle_id, position.vehicle, position.site_id);
        v.stale = false;
        this.addPosition(v, position);
        this.lastSeq = Math.max(this.lastSeq ?? 0, position.seq);
        break;
      }
      case "stale": {
        const v = this.vehicles.get(message.vehicle_id);
        if (v) v.stale = true;
        break;
      }
    }
  }

  /**
   * The ``since`` a reconnect resumes from: the oldest last position among the vehicles that are not stale.
   * With several API processes, positions of different vehicles may arrive out of ``seq`` order, so resuming
   * from the highest seq seen could skip another vehicle's position still in flight; per-vehicle dedupe drops
   * what is replayed twice. Falls back to ``lastSeq`` when no vehicle is moving.
   */
  resumeSeq(): number | null {
    const active = [...this.vehicles.values()]
      .filter((v) => !v.stale && v.position !== null)
      .map((v) => v.position!.seq);
    return active.length > 0 ? Math.min(...active) : this.lastSeq;
  }

  private vehicle(id: number, name: string, siteId: number): VehicleState {
    let v = this.vehicles.get(id);
    if (!v) {
      v = { id, name, siteId, stale: false, position: null, trail: [], heading: null };
      this.vehicles.set(id, v);
    }
    v.name = name;
    return v;
  }

  private addPosition(v: VehicleState, p: PositionMsg): void {
    if (v.position !== null && p.seq <= v.position.seq) return; // a replayed or repeated message
    v.position = p;
    const last = v.trail[v.trail.length - 1];
    if (last && p.t < last.t) v.trail = []; // the vehicle's clock restarted
    v.trail.push({ x: p.x, y: p.y, t: p.t, confidence: p.confidence, lost: p.lost });
    const oldest = p.t - this.trailWindowS;
    const first = v.trail.findIndex((q) => q.t >= oldest);
    if (first > 0) v.trail.splice(0, first);
    v.heading = p.yaw ?? travelHeading(v.trail) ?? v.heading;
  }

  sorted(): VehicleState[] {
    return [...this.vehicles.values()].sort((a, b) => a.name.localeCompare(b.name) || a.id - b.id);
  }
}

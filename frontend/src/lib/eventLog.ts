// The control room's event log in the browser: the server's events (the /api/live snapshot's unacknowledged
// ones, then `event` messages, and this user's acknowledgements as answered), merged so that a late or repeated
// message never undoes a change: an event only ever ends and gets acknowledged, never the other way round.
import { buildUrl, type Schemas } from "../api/client";
import { serverDate } from "./time";

/** One event as the server sends it (``GET /api/events`` items, the snapshot's ``events``). */
export type EventRow = Schemas["EventRead"];
export type EventKind = EventRow["kind"];
/** An ``/api/live`` ``event`` message: the event as it now is, and what changed. */
export type EventMessage = Schemas["LiveEvent"];

/** The kinds in the order the filter lists them, with their wording. */
export const KIND_LABELS: [EventKind, string][] = [
  ["lost", "lost"],
  ["obscured", "camera obscured"],
  ["low_confidence", "low confidence"],
  ["stale", "stale"],
  ["start_known", "known start set"],
];

/** How the end of each kind's condition reads. */
export const END_LABELS: Record<EventKind, string> = {
  lost: "found again",
  obscured: "camera clear",
  low_confidence: "confident again",
  stale: "back",
  start_known: "",
};

export function kindLabel(kind: EventKind): string {
  return KIND_LABELS.find(([k]) => k === kind)?.[1] ?? kind;
}

/** Acknowledged events kept in memory beyond the unacknowledged ones (the newest acknowledgements). */
export const KEEP_ACKNOWLEDGED = 200;

/** Milliseconds of an API time (ISO 8601; compared as instants, not as text). */
const ms = (at: string) => serverDate(at).getTime();

/** The event from ``next`` with whatever ``known`` already had further along (ended, acknowledged). */
export function merged(known: EventRow | undefined, next: EventRow): EventRow {
  if (!known) return next;
  const acknowledged = next.acknowledged_at !== null ? next : known;
  return {
    ...next,
    ended_at: next.ended_at ?? known.ended_at,
    acknowledged_at: acknowledged.acknowledged_at,
    acknowledged_by: acknowledged.acknowledged_by,
    updated_at: ms(next.updated_at) >= ms(known.updated_at) ? next.updated_at : known.updated_at,
  };
}

/** What the events panel shows: one vehicle's (null: all) events of one kind (null: all). */
export interface EventFilters {
  vehicleId: number | null;
  kind: EventKind | null;
}

function passes(e: EventRow, siteId: number, f: EventFilters): boolean {
  return (
    e.site_id === siteId &&
    (f.vehicleId === null || e.vehicle_id === f.vehicleId) &&
    (f.kind === null || e.kind === f.kind)
  );
}

const newestStart = (a: EventRow, b: EventRow) => ms(b.started_at) - ms(a.started_at) || b.id - a.id;
const newestAcknowledged = (a: EventRow, b: EventRow) => ms(b.acknowledged_at!) - ms(a.acknowledged_at!) || b.id - a.id;

export class EventLog {
  private readonly events = new Map<number, EventRow>();

  /**
   * A snapshot's unacknowledged events: they replace the unacknowledged ones held (those acknowledged while the
   * socket was away drop out), merged with what is known of each; acknowledged events held stay.
   */
  reset(unacknowledged: readonly EventRow[]): void {
    for (const [id, e] of this.events) if (e.acknowledged_at === null) this.events.delete(id);
    for (const e of unacknowledged) this.events.set(e.id, merged(this.events.get(e.id), e));
  }

  /** Take in an event's new state; true when it is a new, open, unacknowledged event (an alarm). */
  apply(event: EventRow | EventMessage): boolean {
    const { type: _type, change: _change, ...row } = event as EventMessage;
    const known = this.events.get(row.id);
    const next = merged(known, row);
    this.events.set(row.id, next);
    this.forgetOldAcknowledged();
    return known === undefined && next.ended_at === null && next.acknowledged_at === null;
  }

  get(id: number): EventRow | undefined {
    return this.events.get(id);
  }

  /** The unacknowledged events of a site that pass the filters, newest first (ended ones too). */
  pending(siteId: number, filters: EventFilters): EventRow[] {
    return [...this.events.values()]
      .filter((e) => e.acknowledged_at === null && passes(e, siteId, filters))
      .sort(newestStart);
  }

  /** The acknowledged events held of a site that pass the filters, the latest acknowledgement first. */
  acknowledged(siteId: number, filters: EventFilters, limit = 10): EventRow[] {
    return [...this.events.values()]
      .filter((e) => e.acknowledged_at !== null && passes(e, siteId, filters))
      .sort(newestAcknowledged)
      .slice(0, limit);
  }

  private forgetOldAcknowledged(): void {
    const acknowledged = [...this.events.values()].filter((e) => e.acknowledged_at !== null);
    if (acknowledged.length <= KEEP_ACKNOWLEDGED) return;
    acknowledged.sort(newestAcknowledged);
    for (const e of acknowledged.slice(KEEP_ACKNOWLEDGED)) this.events.delete(e.id);
  }
}

/** ``GET /api/events.csv`` of a site with the panel's filters. */
export function eventsCsvUrl(siteId: number, filters: EventFilters): string {
  return buildUrl("/api/events.csv", {}, { site: siteId, vehicle: filters.vehicleId, kind: filters.kind });
}

// Replay of one vehicle's position history: pick a time range of its clock, load it from
// /api/vehicles/{id}/positions?start=&end=, then play it on the map at a chosen speed, scrub, and follow it.
import { useEffect, useRef, useState } from "react";
import { apiGet } from "../api/client";
import type { VehicleState } from "../lib/liveState";
import { formatFrameTime } from "../lib/time";
import { parseClock, poseAt, rangeBefore, ReplayClock, type TrackPoint } from "../lib/replay";

export const SPEEDS = [1, 2, 5, 10, 30, 60];
const PRESETS_MIN = [1, 5, 30];
const MAX_POSITIONS = 100000;

/** A loaded replay: the track, its clock, and whether the map follows the replayed vehicle. */
export interface ReplaySession {
  vehicleId: number;
  name: string;
  track: TrackPoint[];
  clock: ReplayClock;
  follow: boolean;
  /** Distance from the map's centre to the replayed vehicle, metres (set by the map layer while following). */
  followOffsetM: number | null;
}

interface Props {
  vehicle: VehicleState;
  session: ReplaySession | null;
  onSession: (s: ReplaySession | null) => void;
}

export function ReplayPanel({ vehicle, session, onSession }: Props) {
  const latest = vehicle.position?.t ?? 0;
  const [from, setFrom] = useState(() => rangeBefore(latest, 5)[0]);
  const [to, setTo] = useState(() => rangeBefore(latest, 5)[1]);
  const [error, setError] = useState<string | null>(null);
  const [loading, setLoading] = useState(false);

  const preset = (minutes: number) => {
    const [start, end] = rangeBefore(latest, minutes);
    setFrom(start);
    setTo(end);
  };

  const load = async () => {
    const start = parseClock(from, latest);
    const end = parseClock(to, latest);
    if (start === null || end === null) {
      setError("Write times as YYYY-MM-DD HH:MM:SS, HH:MM:SS, +H:MM:SS (drive time) or seconds.");
      return;
    }
    if (end < start) {
      setError("The end is before the start.");
      return;
    }
    setError(null);
    setLoading(true);
    try {
      const rows = await apiGet(
        "/api/vehicles/{vehicle_id}/positions",
        { vehicle_id: vehicle.id },
        { start, end, limit: MAX_POSITIONS },
      );
      if (rows.length === 0) {
        setError("No positions in that range.");
        onSession(null);
        return;
      }
      const track: TrackPoint[] = rows.map((r) => ({
        t: r.t,
        x: r.x,
        y: r.y,
        yaw: r.yaw,
        confidence: r.confidence,
        lost: r.lost,
        obscured: r.obscured,
      }));
      const clock = new ReplayClock(track[0]!.t, track[track.length - 1]!.t, session?.clock.speed ?? 10);
      onSession({
        vehicleId: vehicle.id,
        name: vehicle.name,
        track,
        clock,
        follow: session?.follow ?? false,
        followOffsetM: null,
      });
    } catch (e) {
      setError(e instanceof Error ? e.message : String(e));
    } finally {
      setLoading(false);
    }
  };

  const mine = session !== null && session.vehicleId === vehicle.id ? session : null;
  return (
    <section data-testid="replay-range">
      <h3>Replay</h3>
      <div className="row">
        <label>
          From <input data-testid="replay-from" value={from} onChange={(e) => setFrom(e.target.value)} size={19} />
        </label>
        <label>
          To <input data-testid="replay-to" value={to} onChange={(e) => setTo(e.target.value)} size={19} />
        </label>
      </div>
      <div className="row">
        {PRESETS_MIN.map((m) => (
          <button key={m} onClick={() => preset(m)} data-testid={`replay-last-${m}`}>
            last {m} min
          </button>
        ))}
        <span className="spacer" />
        <button className="primary" data-testid="replay-load" disabled={loading} onClick={() => void load()}>
          {loading ? "Loading…" : "Load"}
        </button>
      </div>
      {error && (
        <p className="muted" data-testid="replay-error">
          {error}
        </p>
      )}
      {mine && <ReplayPlayer session={mine} onSession={onSession} />}
    </section>
  );
}

function ReplayPlayer({
  session,
  onSession,
}: {
  session: ReplaySession;
  onSession: (s: ReplaySession | null) => void;
}) {
  const { clock, track } = session;
  const [, setFrame] = useState(0);
  const last = useRef(0);

  useEffect(() => {
    last.current = performance.now();
    let raf = 0;
    let shown = 0;
    const tick = (now: number) => {
      clock.tick(now - last.current);
      last.current = now;
      if (now - shown > 100) {
        shown = now;
        setFrame((f) => f + 1); // the controls follow the clock at 10 Hz; the map layer every frame
      }
      raf = requestAnimationFrame(tick);
    };
    raf = requestAnimationFrame(tick);
    return () => cancelAnimationFrame(raf);
  }, [clock]);

  const pose = poseAt(track, clock.now);
  const toggle = () => {
    if (clock.playing) clock.pause();
    else clock.play();
    last.current = performance.now();
    setFrame((f) => f + 1);
  };
  return (
    <div
      data-testid="replay-panel"
      data-state={clock.playing ? "playing" : "paused"}
      data-count={track.length}
      data-t={clock.now.toFixed(2)}
      data-index={pose?.index ?? -1}
      data-follow-offset={session.followOffsetM === null ? "" : session.followOffsetM.toFixed(2)}
    >
      <div className="row">
        <button className="primary" data-testid="replay-play" onClick={toggle}>
          {clock.playing ? "Pause" : "Play"}
        </button>
        <select
          data-testid="replay-speed"
          value={String(clock.speed)}
          onChange={(e) => {
            // the clock lives outside React (the map layer reads it every frame); the re-render is forced below
            // eslint-disable-next-line react-hooks/immutability
            clock.speed = Number(e.target.value);
            setFrame((f) => f + 1);
          }}
        >
          {SPEEDS.map((s) => (
            <option key={s} value={String(s)}>
              {s}×
            </option>
          ))}
        </select>
        <label>
          <input
            type="checkbox"
            data-testid="replay-follow"
            checked={session.follow}
            onChange={(e) => onSession({ ...session, follow: e.target.checked, followOffsetM: null })}
          />{" "}
          follow
        </label>
        <span className="spacer" />
        <button data-testid="replay-close" onClick={() => onSession(null)}>
          Back to live
        </button>
      </div>
      <input
        type="range"
        data-testid="replay-scrubber"
        style={{ width: "100%" }}
        min={clock.start}
        max={clock.end}
        step="any"
        value={clock.now}
        onChange={(e) => {
          clock.seek(Number(e.target.value));
          setFrame((f) => f + 1);
        }}
      />
      <div className="row muted" data-testid="replay-time">
        {formatFrameTime(clock.now)} · {pose ? `E ${pose.x.toFixed(1)} N ${pose.y.toFixed(1)}` : "–"} · {track.length}{" "}
        positions, {formatFrameTime(clock.start)} – {formatFrameTime(clock.end)}
      </div>
    </div>
  );
}

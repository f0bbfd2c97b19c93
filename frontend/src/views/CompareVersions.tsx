// "Compare versions": pick two map versions (A, B) and see B's trajectories drawn over A's on the plan, with
// links where frames moved and the server's displacement figures (``GET /api/sites/{id}/maps/compare``).
import { useEffect, useMemo, useRef, useState } from "react";
import { ApiError, apiGet, type Schemas } from "../api/client";
import { defaultPair, displacements, type PoseArrays } from "../lib/compare";
import { CompareLayer } from "../map/CompareLayer";
import type { MapCtx } from "../map/MineMap";

type Stats = Schemas["MapCompareRead"];

interface Props {
  siteId: number;
  versions: number[];
  ctx: MapCtx | null;
}

const metres = (v: number | null | undefined) => (v === null || v === undefined ? "–" : `${v.toFixed(2)} m`);

export function CompareVersions({ siteId, versions, ctx }: Props) {
  const [on, setOn] = useState(false);
  const [pair, setPair] = useState<{ a: number; b: number } | null>(null);
  const [versionsSeen, setVersionsSeen] = useState<number[] | null>(null);
  // each answer remembers the request it belongs to (site and pair), so a stale one is never shown
  const [answer, setAnswer] = useState<{ key: string; a: PoseArrays; b: PoseArrays; stats: Stats } | null>(null);
  const [failure, setFailure] = useState<{ key: string; text: string } | null>(null);
  const key = pair ? `${siteId}:${pair.a}:${pair.b}` : null;
  const loaded = answer !== null && answer.key === key ? answer : null;
  const error = failure !== null && failure.key === key ? failure.text : null;
  const cache = useRef(new Map<number, Promise<PoseArrays>>());

  useEffect(() => {
    cache.current.clear();
  }, [siteId]);
  if (versionsSeen !== versions) {
    // new versions: keep the pair while both still exist
    setVersionsSeen(versions);
    setPair((p) => (p && versions.includes(p.a) && versions.includes(p.b) ? p : defaultPair(versions)));
  }

  useEffect(() => {
    if (!on || !pair || key === null) return;
    let cancelled = false;
    const poses = (version: number) => {
      let p = cache.current.get(version);
      if (!p) {
        p = apiGet("/api/sites/{site_id}/maps/{version}/poses", { site_id: siteId, version }, { limit: 1000000 });
        cache.current.set(version, p);
        p.catch(() => cache.current.delete(version));
      }
      return p;
    };
    void (async () => {
      try {
        const [a, b, stats] = await Promise.all([
          poses(pair.a),
          poses(pair.b),
          apiGet("/api/sites/{site_id}/maps/compare", { site_id: siteId }, { a: pair.a, b: pair.b }),
        ]);
        if (!cancelled) setAnswer({ key, a, b, stats });
      } catch (e) {
        if (!cancelled) setFailure({ key, text: e instanceof ApiError ? e.message : String(e) });
      }
    })();
    return () => {
      cancelled = true;
    };
  }, [on, pair, siteId, key]);

  const moved = useMemo(() => (loaded ? displacements(loaded.a, loaded.b) : []), [loaded]);
  const sorted = [...versions].sort((p, q) => q - p);
  const picker = (which: "a" | "b") => (
    <select
      data-testid={`compare-${which}`}
      value={pair?.[which] ?? ""}
      onChange={(e) => pair && setPair({ ...pair, [which]: Number(e.target.value) })}
    >
      {sorted.map((v) => (
        <option key={v} value={v}>
          v{v}
        </option>
      ))}
    </select>
  );

  if (versions.length < 2) return null;
  return (
    <div data-testid="compare-panel">
      <div className="row">
        <label title="Draw version B's trajectories over version A's">
          <input type="checkbox" data-testid="toggle-compare" checked={on} onChange={(e) => setOn(e.target.checked)} />{" "}
          compare versions
        </label>
        {on && (
          <>
            <span className="muted">A</span>
            {picker("a")}
            <span className="muted" style={{ color: "#ffd43b" }}>
              B
            </span>
            {picker("b")}
          </>
        )}
      </div>
      {on && error && <div className="error">{error}</div>}
      {on && loaded && pair && (
        <div
          className="muted"
          data-testid="compare-summary"
          data-state="shown"
          data-a={loaded.stats.version_a}
          data-b={loaded.stats.version_b}
          data-frames={loaded.stats.frames}
        >
          v{loaded.stats.version_b} over v{loaded.stats.version_a}: {loaded.stats.frames} frames in both, moved mean{" "}
          {metres(loaded.stats.mean_m)}, p95 {metres(loaded.stats.p95_m)}, max {metres(loaded.stats.max_m)}
          {loaded.stats.only_in_b > 0 ? ` · ${loaded.stats.only_in_b} new in B` : ""}
        </div>
      )}
      {on && loaded && ctx && <CompareLayer ctx={ctx} a={loaded.a} b={loaded.b} moved={moved} />}
    </div>
  );
}

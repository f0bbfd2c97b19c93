// Grounding workstation: the latest map version's trajectories over the plan, a keyframe strip per drive,
// ground the selected keyframe by clicking its surveyed point, a residual table (sortable, colour-coded),
// delete and undo, and "Build map" with the job's progress.
import { useCallback, useEffect, useMemo, useState } from "react";
import { ApiError, apiDelete, apiDownload, apiGet, apiPost, apiPutForm, type Schemas } from "../api/client";
import { MineMap, type MapCtx } from "../map/MineMap";
import { TrajectoryLayer, type Closure, type Poses } from "../map/TrajectoryLayer";
import { joinResiduals, sortRows, type SortDir, type SortKey } from "../lib/residuals";
import { driveColour, rgbCss } from "../lib/colours";
import { snapPoint } from "../lib/snap";
import { AuthImage } from "./AuthImage";
import { GroundingsTable, ShortcutHelp } from "./GroundingsTable";

type Drive = Schemas["DriveRead"];
type Job = Schemas["JobRead"];
type Action = { kind: "created"; id: number; driveId: number; frame: number; x: number; y: number } | {
  kind: "deleted";
  driveId: number;
  frame: number;
  x: number;
  y: number;
};

const KEYFRAME_STRIDE = 10;
const STRIP_PAGE = 12;
const SNAP_TOLERANCE_PX = 12;
const PLAY_STEP_MS = 250; // keyframe strip playback: one keyframe per step

export function GroundingView({ siteId, editable }: { siteId: number; editable: boolean }) {
  const [drives, setDrives] = useState<Drive[]>([]);
  const [version, setVersion] = useState<number | null>(null);
  const [poses, setPoses] = useState<Poses | null>(null);
  const [closures, setClosures] = useState<Closure[]>([]);
  const [showClosures, setShowClosures] = useState(true);
  const [groundings, setGroundings] = useState<Schemas["GroundingRead"][]>([]);
  const [residuals, setResiduals] = useState<Schemas["ResidualRead"][]>([]);
  const [driveId, setDriveId] = useState<number | null>(null);
  const [frame, setFrame] = useState<number | null>(null);
  const [page, setPage] = useState(0);
  const [sort, setSort] = useState<{ key: SortKey; dir: SortDir }>({ key: "distance", dir: "desc" });
  const [undo, setUndo] = useState<Action[]>([]);
  const [redo, setRedo] = useState<Action[]>([]);
  const [message, setMessage] = useState<string | null>(null);
  const [job, setJob] = useState<Job | null>(null);
  const [ctx, setCtx] = useState<MapCtx | null>(null);
  const [snapOn, setSnapOn] = useState(false);
  const [playing, setPlaying] = useState(false);
  const [help, setHelp] = useState(false);

  const loadGroundings = useCallback(async () => {
    const page = await apiGet("/api/sites/{site_id}/groundings", { site_id: siteId }, { limit: 10000 });
    setGroundings(page.items);
  }, [siteId]);

  const loadVersion = useCallback(async () => {
    const versions = await apiGet("/api/sites/{site_id}/maps", { site_id: siteId }, { limit: 500 });
    const latest = versions.items.reduce<number | null>((m, v) => (m === null || v.version > m ? v.version : m), null);
    setVersion(latest);
    if (latest === null) {
      setPoses(null);
      setClosures([]);
      setResiduals([]);
      return;
    }
    const p = { site_id: siteId, version: latest };
    const [ps, cs, rs] = await Promise.all([
      apiGet("/api/sites/{site_id}/maps/{version}/poses", p, { limit: 1000000 }),
      apiGet("/api/sites/{site_id}/maps/{version}/closures", p),
      apiGet("/api/sites/{site_id}/maps/{version}/residuals", p),
    ]);
    setPoses(ps);
    setClosures(cs);
    setResiduals(rs);
  }, [siteId]);

  useEffect(() => {
    void (async () => {
      const page = await apiGet("/api/sites/{site_id}/drives", { site_id: siteId }, { limit: 500 });
      const mapping = page.items.filter((d) => d.kind === "mapping");
      setDrives(mapping);
      setDriveId((d) => d ?? mapping[0]?.id ?? null);
    })();
    void loadVersion();
    void loadGroundings();
  }, [siteId, loadVersion, loadGroundings]);

  const drive = drives.find((d) => d.id === driveId) ?? null;
  const keyframes = useMemo(() => {
    if (!drive) return [];
    if (poses) {
      const frames = poses.frame.filter((_, i) => poses.drive_id[i] === drive.id);
      return frames.filter((_, i) => i % KEYFRAME_STRIDE === 0);
    }
    return Array.from({ length: Math.ceil(drive.frame_count / KEYFRAME_STRIDE) }, (_, i) => i * KEYFRAME_STRIDE);
  }, [drive, poses]);
  const pageCount = Math.max(1, Math.ceil(keyframes.length / STRIP_PAGE));
  const stripFrames = keyframes.slice(page * STRIP_PAGE, (page + 1) * STRIP_PAGE);

  const rows = useMemo(
    () => sortRows(joinResiduals(groundings, residuals), sort.key, sort.dir),
    [groundings, residuals, sort],
  );

  const step = useCallback(
    (delta: number) => {
      if (keyframes.length === 0) return;
      const i = frame === null ? 0 : keyframes.indexOf(frame);
      const next = keyframes[Math.min(keyframes.length - 1, Math.max(0, (i < 0 ? 0 : i) + delta))]!;
      setFrame(next);
      setPage(Math.floor(keyframes.indexOf(next) / STRIP_PAGE));
    },
    [frame, keyframes],
  );

  useEffect(() => {
    if (!playing) return;
    const last = keyframes[keyframes.length - 1];
    if (frame !== null && frame === last) {
      setPlaying(false);
      return;
    }
    const timer = setTimeout(() => step(1), PLAY_STEP_MS);
    return () => clearTimeout(timer);
  }, [playing, frame, keyframes, step]);

  const ground = async (clickX: number, clickY: number) => {
    if (!editable || driveId === null || frame === null) return;
    let x = clickX;
    let y = clickY;
    if (snapOn && ctx?.snap.current) {
      const tolerance = SNAP_TOLERANCE_PX * (ctx.map.getView().getResolution() ?? 0);
      ({ x, y } = snapPoint(ctx.snap.current, clickX, clickY, tolerance));
    }
    try {
      const g = await apiPost("/api/drives/{drive_id}/groundings", { drive_id: driveId }, { frame, x, y });
      setUndo((u) => [...u, { kind: "created", id: g.id, driveId, frame, x, y }]);
      setRedo([]);
      setMessage(`grounded ${drive?.name ?? driveId} frame ${frame} at E ${x.toFixed(2)} N ${y.toFixed(2)}`);
      await loadGroundings();
    } catch (e) {
      setMessage(e instanceof ApiError ? e.message : String(e));
    }
  };

  const remove = async (id: number) => {
    const g = groundings.find((r) => r.id === id);
    if (!g) return;
    await apiDelete("/api/groundings/{grounding_id}", { grounding_id: id });
    setUndo((u) => [...u, { kind: "deleted", driveId: g.drive_id, frame: g.frame, x: g.x_m, y: g.y_m }]);
    setRedo([]);
    await loadGroundings();
  };

  // Undo and redo: each step replays the inverse call (a re-created grounding gets a new id).
  const invert = async (a: Action): Promise<Action> => {
    if (a.kind === "created") {
      await apiDelete("/api/groundings/{grounding_id}", { grounding_id: a.id });
      return { kind: "deleted", driveId: a.driveId, frame: a.frame, x: a.x, y: a.y };
    }
    const g = await apiPost("/api/drives/{drive_id}/groundings", { drive_id: a.driveId }, { frame: a.frame, x: a.x, y: a.y });
    return { kind: "created", id: g.id, driveId: a.driveId, frame: a.frame, x: a.x, y: a.y };
  };

  const replay = async (from: Action[], setFrom: typeof setUndo, setTo: typeof setUndo, verb: string) => {
    const last = from[from.length - 1];
    if (!last) return;
    setFrom(from.slice(0, -1));
    try {
      const done = await invert(last);
      setTo((t) => [...t, done]);
      setMessage(`${verb}: ${done.kind === "created" ? "grounding restored" : "grounding removed"}`);
    } catch (e) {
      setMessage(e instanceof ApiError ? e.message : String(e));
    }
    await loadGroundings();
  };
  const undoLast = () => replay(undo, setUndo, setRedo, "undone");
  const redoLast = () => replay(redo, setRedo, setUndo, "redone");

  useEffect(() => {
    const onKey = (e: KeyboardEvent) => {
      if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement) return;
      if (e.key === "?") setHelp((h) => !h);
      else if (e.key === "Escape") setHelp(false);
      else if (e.key === " ") {
        e.preventDefault();
        setPlaying((p) => !p);
      } else if (e.key === "ArrowRight" || e.key === "n") step(1);
      else if (e.key === "ArrowLeft" || e.key === "p") step(-1);
      else if (editable && (e.key === "u" || (e.ctrlKey && e.key === "z"))) void undoLast();
      else if (editable && (e.key === "r" || (e.ctrlKey && e.key === "y"))) void redoLast();
    };
    window.addEventListener("keydown", onKey);
    return () => window.removeEventListener("keydown", onKey);
  });

  const exportCsv = async () => {
    if (!drive) return;
    await apiDownload(`/api/drives/${drive.id}/groundings.csv`, `${drive.name}-groundings.csv`);
  };

  const importCsv = async (file: File) => {
    if (!drive) return;
    const form = new FormData();
    form.append("file", file);
    try {
      const result = await apiPutForm("/api/drives/{drive_id}/groundings.csv", { drive_id: drive.id }, form);
      setMessage(`imported ${result.imported} groundings into ${drive.name} (replacing its old ones)`);
      setUndo([]);
      setRedo([]);
    } catch (e) {
      setMessage(e instanceof ApiError ? e.message : String(e));
    }
    await loadGroundings();
  };

  const build = async () => {
    try {
      setJob(await apiPost("/api/sites/{site_id}/maps", { site_id: siteId }, { preset: "fast" }));
    } catch (e) {
      setMessage(e instanceof ApiError ? e.message : String(e));
    }
  };

  useEffect(() => {
    if (!job || ["succeeded", "failed", "cancelled"].includes(job.status)) return;
    const timer = setTimeout(async () => {
      const next = await apiGet("/api/jobs/{job_id}", { job_id: job.id });
      setJob(next);
      if (next.status === "succeeded") await loadVersion();
    }, 1000);
    return () => clearTimeout(timer);
  }, [job, loadVersion]);

  const flyTo = (x: number, y: number) => {
    if (ctx) ctx.map.getView().animate({ center: ctx.origin.toLocal(x, y), zoom: Math.max(ctx.map.getView().getZoom() ?? 0, 5), duration: 400 });
  };

  return (
    <>
      <MineMap
        key={siteId}
        siteId={siteId}
        onMapClick={(x, y) => void ground(x, y)}
        tools={
          <>
          <label>
            <input type="checkbox" data-testid="toggle-closures" checked={showClosures} onChange={(e) => setShowClosures(e.target.checked)} />{" "}
            loop closures ({closures.length})
          </label>
          {editable && (
            <label title="Snap groundings to DXF vertices, else to centrelines">
              <input type="checkbox" data-testid="toggle-snap" checked={snapOn} onChange={(e) => setSnapOn(e.target.checked)} /> snap
            </label>
          )}
          </>
        }
        overlay={(c) => (
          <>
            <CtxSink ctx={c} onCtx={setCtx} />
            <TrajectoryLayer
              ctx={c}
              poses={poses}
              closures={closures}
              showClosures={showClosures}
              groundings={joinResiduals(groundings, residuals)}
              selected={driveId !== null && frame !== null ? { driveId, frame } : null}
              keyframeStride={KEYFRAME_STRIDE}
            />
          </>
        )}
      />
      <aside className="side" data-testid="grounding-panel">
        <div className="row">
          <h2 style={{ margin: 0 }}>Grounding</h2>
          <span className="spacer" />
          <span className="muted" data-testid="map-version">{version === null ? "no map yet" : `map v${version}`}</span>
          {editable && (
            <button className="primary" data-testid="build-map" onClick={build} disabled={job !== null && !["succeeded", "failed", "cancelled"].includes(job.status)}>
              Build map
            </button>
          )}
        </div>
        {job && (
          <div data-testid="build-job" data-status={job.status}>
            <div className="progress"><div style={{ width: `${Math.round(job.progress * 100)}%` }} /></div>
            <span className="muted">job {job.id}: {job.status} {job.stage} {Math.round(job.progress * 100)}%</span>
            {job.error && <div className="error">{job.error}</div>}
          </div>
        )}
        <div className="row">
          <select data-testid="drive-select" value={driveId ?? ""} onChange={(e) => { setDriveId(Number(e.target.value)); setFrame(null); setPage(0); }}>
            {drives.map((d) => (
              <option key={d.id} value={d.id}>{d.name} ({d.frame_count} frames)</option>
            ))}
          </select>
          {drive && <span className="dot" style={{ background: rgbCss(driveColour(drive.id)) }} />}
          <span className="spacer" />
          <button data-testid="play" onClick={() => setPlaying((p) => !p)} title="Play the drive's keyframes (space)">
            {playing ? "❚❚" : "▶"}
          </button>
          <button onClick={() => setPage((p) => Math.max(0, p - 1))} disabled={page === 0}>‹</button>
          <span className="muted">{page + 1}/{pageCount}</span>
          <button onClick={() => setPage((p) => Math.min(pageCount - 1, p + 1))} disabled={page >= pageCount - 1}>›</button>
        </div>
        <div className="strip" data-testid="keyframe-strip">
          {driveId !== null && stripFrames.map((f) => (
            <button key={f} className={`thumb ${f === frame ? "selected" : ""}`} data-testid={`keyframe-${f}`} data-frame={f} onClick={() => setFrame(f)}>
              <AuthImage src={`/api/drives/${driveId}/frames/${f}/thumbnail?width=96`} alt={`frame ${f}`} />
              <span>#{f}</span>
            </button>
          ))}
        </div>
        {frame !== null && driveId !== null && (
          <div data-testid="selected-frame" data-frame={frame}>
            <AuthImage className="bigframe" src={`/api/drives/${driveId}/frames/${frame}`} alt={`frame ${frame} large`} />
            <div className="muted">
              {drive?.name} frame {frame}
              {editable ? " · click its surveyed point on the plan to ground it" : ""}
            </div>
          </div>
        )}
        {message && <p data-testid="grounding-message">{message}</p>}
        <div className="row">
          <h3 style={{ margin: 0 }}>Groundings ({groundings.length})</h3>
          <span className="spacer" />
          <button onClick={() => void exportCsv()} disabled={!drive} data-testid="export-csv" title="Export this drive's groundings">
            CSV ↓
          </button>
          {editable && (
            <label className="filebutton" title={`Import groundings.csv into ${drive?.name ?? "the drive"} (replaces its groundings)`}>
              CSV ↑
              <input
                type="file"
                accept=".csv,text/csv"
                data-testid="import-csv"
                onChange={(e) => {
                  const file = e.target.files?.[0];
                  e.target.value = "";
                  if (file) void importCsv(file);
                }}
              />
            </label>
          )}
          {editable && (
            <button data-testid="undo" onClick={undoLast} disabled={undo.length === 0} title="Undo (u or Ctrl+Z)">
              Undo
            </button>
          )}
          {editable && (
            <button data-testid="redo" onClick={redoLast} disabled={redo.length === 0} title="Redo (r or Ctrl+Y)">
              Redo
            </button>
          )}
        </div>
        <GroundingsTable
          rows={rows}
          sort={sort}
          onSort={setSort}
          editable={editable}
          onFly={flyTo}
          onDelete={(id) => void remove(id)}
        />
        <p className="muted">
          Press <button onClick={() => setHelp(true)} data-testid="help">?</button> for keyboard shortcuts
        </p>
        {help && <ShortcutHelp editable={editable} onClose={() => setHelp(false)} />}
      </aside>
    </>
  );
}

function CtxSink({ ctx, onCtx }: { ctx: MapCtx; onCtx: (c: MapCtx) => void }) {
  useEffect(() => onCtx(ctx), [ctx, onCtx]);
  return null;
}

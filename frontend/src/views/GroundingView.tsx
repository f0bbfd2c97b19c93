// Grounding workstation: the latest map version's trajectories over the plan, a keyframe strip per drive,
// ground the selected keyframe in an explicit placing mode (usePlacement: Place or g, then a click on its
// surveyed point; a doubtful point is confirmed first), select a grounding by its keyframe or its square on the
// plan, drag a grounding to adjust it, a residual table
// (sortable, colour-coded), delete, undo/redo, CSV import/export, "Build map" with the job's progress, a map
// version's export (MapExport), and two map versions compared as an overlay.
import { useCallback, useEffect, useMemo, useRef, useState } from "react";
import { unByKey } from "ol/Observable";
import { apiGet, apiPatch, type Schemas } from "../api/client";
import { MineMap, type MapCtx } from "../map/MineMap";
import { TrajectoryLayer, poseIndex, type Closure, type Poses } from "../map/TrajectoryLayer";
import { GroundingMarkers } from "../map/GroundingMarkers";
import { keyframesOf, pageOf, stepFrame } from "../lib/frameNav";
import {
  EXAGGERATIONS,
  filterByDrive,
  joinResiduals,
  sortRows,
  type GroundingRow,
  type SortDir,
  type SortKey,
} from "../lib/residuals";
import { snapPoint } from "../lib/snap";
import { BuildMap } from "./BuildMap";
import { CompareVersions } from "./CompareVersions";
import { FrameView } from "./FrameView";
import { GroundingsCsv } from "./GroundingsCsv";
import { MapExport } from "./MapExport";
import { GroundingsTable, ShortcutHelp } from "./GroundingsTable";
import { KeyframeStrip } from "./KeyframeStrip";
import { useGroundingEdits } from "./useGroundingEdits";
import { usePlacement, type PlacementTarget } from "./usePlacement";
import { PlacingPanel } from "./PlacingPanel";
import { ResidualSummary } from "./ResidualSummary";

type Drive = Schemas["DriveRead"];

const KEYFRAME_STRIDE = 10;
const STRIP_PAGE = 12;
const SNAP_TOLERANCE_PX = 12;
const PLAY_STEP_MS = 250; // keyframe strip playback: one keyframe per step
const PICK_TOLERANCE_PX = 8; // a click this close to a grounding's square selects it

export function GroundingView({ siteId, editable }: { siteId: number; editable: boolean }) {
  const [drives, setDrives] = useState<Drive[]>([]);
  const [versions, setVersions] = useState<number[]>([]);
  const [poses, setPoses] = useState<Poses | null>(null);
  const [closures, setClosures] = useState<Closure[]>([]);
  const [showClosures, setShowClosures] = useState(true);
  const [groundings, setGroundings] = useState<Schemas["GroundingRead"][]>([]);
  const [residuals, setResiduals] = useState<Schemas["ResidualRead"][]>([]);
  const [summary, setSummary] = useState<Schemas["ResidualSummaryRead"] | null>(null);
  const [tableDrive, setTableDrive] = useState<number | null>(null);
  const [driveId, setDriveId] = useState<number | null>(null);
  const [frame, setFrame] = useState<number | null>(null);
  const [page, setPage] = useState(0);
  const [sort, setSort] = useState<{ key: SortKey; dir: SortDir }>({ key: "distance", dir: "desc" });
  const [message, setMessage] = useState<string | null>(null);
  const [ctx, setCtx] = useState<MapCtx | null>(null);
  const [snapOn, setSnapOn] = useState(false);
  const [playing, setPlaying] = useState(false);
  const [help, setHelp] = useState(false);
  const [exaggeration, setExaggeration] = useState<number>(1);
  const [large, setLarge] = useState(false);
  const version = versions.length > 0 ? Math.max(...versions) : null;

  const loadGroundings = useCallback(async () => {
    const page = await apiGet("/api/sites/{site_id}/groundings", { site_id: siteId }, { limit: 10000 });
    setGroundings(page.items);
  }, [siteId]);

  const loadVersion = useCallback(async () => {
    const list = await apiGet("/api/sites/{site_id}/maps", { site_id: siteId }, { limit: 500 });
    const all = list.items.map((v) => v.version);
    const latest = all.length > 0 ? Math.max(...all) : null;
    if (latest === null) {
      setPoses(null);
      setClosures([]);
      setResiduals([]);
      setSummary(null);
      setVersions([]);
      return;
    }
    const p = { site_id: siteId, version: latest };
    const [ps, cs, rs, sm] = await Promise.all([
      apiGet("/api/sites/{site_id}/maps/{version}/poses", p, { limit: 1000000 }),
      apiGet("/api/sites/{site_id}/maps/{version}/closures", p),
      apiGet("/api/sites/{site_id}/maps/{version}/residuals", p),
      apiGet("/api/sites/{site_id}/maps/{version}/residuals/summary", p),
    ]);
    setPoses(ps);
    setClosures(cs);
    setResiduals(rs);
    setSummary(sm);
    setVersions(all);
  }, [siteId]);

  useEffect(() => {
    void (async () => {
      const page = await apiGet("/api/sites/{site_id}/drives", { site_id: siteId }, { limit: 500 });
      const mapping = page.items.filter((d) => d.kind === "mapping");
      setDrives(mapping);
      setDriveId((d) => d ?? mapping[0]?.id ?? null);
    })();
    // both set state only after their requests resolve
    // eslint-disable-next-line react-hooks/set-state-in-effect
    void loadVersion();
    void loadGroundings();
  }, [siteId, loadVersion, loadGroundings]);

  const edits = useGroundingEdits({ groundings, reload: loadGroundings, say: setMessage });

  const drive = drives.find((d) => d.id === driveId) ?? null;
  /** The keyframes of drive ``id``: every KEYFRAME_STRIDE-th frame of the map's poses, else of its frames. */
  const keyframesFor = useCallback(
    (id: number): number[] => {
      if (poses) {
        const frames = poses.frame.filter((_, i) => poses.drive_id[i] === id);
        return frames.filter((_, i) => i % KEYFRAME_STRIDE === 0);
      }
      return keyframesOf(drives.find((d) => d.id === id)?.frame_count ?? 0, KEYFRAME_STRIDE);
    },
    [poses, drives],
  );
  const keyframes = useMemo(() => (drive ? keyframesFor(drive.id) : []), [drive, keyframesFor]);
  const pageCount = Math.max(1, Math.ceil(keyframes.length / STRIP_PAGE));
  const stripFrames = keyframes.slice(page * STRIP_PAGE, (page + 1) * STRIP_PAGE);

  const joined = useMemo(() => joinResiduals(groundings, residuals), [groundings, residuals]);
  const rows = useMemo(
    () => sortRows(filterByDrive(joined, tableDrive), sort.key, sort.dir),
    [joined, tableDrive, sort],
  );
  const setEnabled = async (id: number, enabled: boolean): Promise<void> => {
    try {
      await apiPatch("/api/groundings/{grounding_id}", { grounding_id: id }, { enabled });
      setMessage(enabled ? "grounding enabled for the next build" : "grounding left out of the next build");
    } catch (err) {
      setMessage(err instanceof Error ? err.message : String(err));
    }
    await loadGroundings();
  };
  const poseAt = useMemo(() => (poses ? poseIndex(poses) : new Map<string, [number, number]>()), [poses]);
  const groundedFrames = useMemo(
    () => new Set(groundings.filter((g) => g.drive_id === driveId).map((g) => g.frame)),
    [groundings, driveId],
  );

  /** Select frame ``f`` of the drive shown (any frame, not only a keyframe); the strip turns to its page. */
  const show = useCallback(
    (f: number) => {
      setFrame(f);
      setPage(pageOf(keyframes, f, STRIP_PAGE));
    },
    [keyframes],
  );

  const step = useCallback(
    (delta: number) => {
      const next = stepFrame(keyframes, frame, delta);
      if (next !== null) show(next);
    },
    [frame, keyframes, show],
  );

  useEffect(() => {
    if (!playing) return;
    const atLast = frame !== null && frame === keyframes[keyframes.length - 1];
    const timer = setTimeout(() => (atLast ? setPlaying(false) : step(1)), atLast ? 0 : PLAY_STEP_MS);
    return () => clearTimeout(timer);
  }, [playing, frame, keyframes, step]);

  // the plan point under the pointer (mine grid), for grounding from the keyboard ("g")
  const pointer = useRef<[number, number] | null>(null);
  useEffect(() => {
    if (!ctx) return;
    const key = ctx.map.on("pointermove", (ev) => {
      pointer.current = ctx.origin.toWorld(ev.coordinate[0]!, ev.coordinate[1]!);
    });
    return () => unByKey(key);
  }, [ctx]);

  /** The point a click at (x, y) means: snapped to the plan when snapping is on, with a label's station. */
  const snapped = useCallback(
    (x: number, y: number): { x: number; y: number; station?: string } => {
      if (!snapOn || !ctx?.snap.current) return { x, y };
      const tolerance = SNAP_TOLERANCE_PX * (ctx.map.getView().getResolution() ?? 0);
      const to = snapPoint(ctx.snap.current, x, y, tolerance);
      return to.kind === "label" ? { x: to.x, y: to.y, station: to.station } : { x: to.x, y: to.y };
    },
    [snapOn, ctx],
  );

  const selectedGrounding = groundings.find((g) => g.drive_id === driveId && g.frame === frame) ?? null;
  const target: PlacementTarget | null = useMemo(
    () =>
      driveId === null || frame === null
        ? null
        : {
            driveId,
            frame,
            groundingId: selectedGrounding?.id ?? null,
            estimate: poseAt.get(`${driveId}#${frame}`) ?? null,
          },
    [driveId, frame, selectedGrounding?.id, poseAt],
  );
  const driveName = drive?.name;
  const placement = usePlacement({
    enabled: editable,
    target,
    walls: () => ctx?.walls.current ?? null,
    snap: snapped,
    write: (t: PlacementTarget, x: number, y: number, station?: string) =>
      t.groundingId === null
        ? edits.create(t.driveId, t.frame, x, y, driveName ?? String(t.driveId), station)
        : edits.move(t.groundingId, x, y),
  });

  // the plan point under the pointer as state while placing, so that the placing panel can name the station a
  // click there would take
  const [placingAt, setPlacingAt] = useState<[number, number] | null>(null);
  useEffect(() => {
    if (!ctx || !placement.placing) return;
    const key = ctx.map.on("pointermove", (ev) => {
      setPlacingAt(ctx.origin.toWorld(ev.coordinate[0]!, ev.coordinate[1]!));
    });
    return () => {
      unByKey(key);
      setPlacingAt(null);
    };
  }, [ctx, placement.placing]);
  const stationUnder = placement.placing && placingAt ? (snapped(...placingAt).station ?? null) : null;

  /** Select frame ``f`` of drive ``id`` (and the strip page that shows it). */
  const select = (id: number, f: number) => {
    setDriveId(id);
    setFrame(f);
    setPage(pageOf(keyframesFor(id), f, STRIP_PAGE));
  };

  /** A residual-table row: the plan flies to its surveyed point and its keyframe opens. */
  const openRow = (row: GroundingRow) => {
    flyTo(row.x, row.y);
    select(row.driveId, row.frame);
  };

  /** A click on the plan: places in the placing mode, else selects the grounding whose square it hits. */
  const clickMap = (x: number, y: number) => {
    if (placement.place(x, y) || !ctx) return;
    const tolerance = PICK_TOLERANCE_PX * (ctx.map.getView().getResolution() ?? 0);
    let best: Schemas["GroundingRead"] | null = null;
    let bestD = tolerance;
    for (const g of groundings) {
      const d = Math.hypot(g.x_m - x, g.y_m - y);
      if (d <= bestD) [best, bestD] = [g, d];
    }
    if (best) select(best.drive_id, best.frame);
  };

  const moveGrounding = async (id: number, x: number, y: number) => {
    const to = snapped(x, y);
    await edits.move(id, to.x, to.y);
  };

  useEffect(() => {
    const onKey = (e: KeyboardEvent) => {
      if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement) return;
      if (placement.pending) return; // the confirmation has the keyboard
      if (e.key === "?") setHelp((h) => !h);
      else if (e.key === "Escape") setHelp(false);
      else if (e.key === " ") {
        e.preventDefault();
        setPlaying((p) => !p);
      } else if (e.key === "ArrowRight" || e.key === "n") step(1);
      else if (e.key === "ArrowLeft" || e.key === "p") step(-1);
      else if (editable && e.key === "g") {
        if (!placement.placing) placement.begin();
        else if (pointer.current) placement.place(...pointer.current);
      } else if (editable && (e.key === "x" || e.key === "Delete")) {
        if (selectedGrounding) void edits.remove(selectedGrounding.id);
      } else if (editable && (e.key === "u" || (e.ctrlKey && e.key === "z"))) void edits.undo();
      else if (editable && (e.key === "r" || (e.ctrlKey && e.key === "y"))) void edits.redo();
    };
    window.addEventListener("keydown", onKey);
    return () => window.removeEventListener("keydown", onKey);
  });

  const flyTo = (x: number, y: number) => {
    if (!ctx) return;
    const view = ctx.map.getView();
    view.animate({ center: ctx.origin.toLocal(x, y), zoom: Math.max(view.getZoom() ?? 0, 5), duration: 400 });
  };

  return (
    <>
      {large && drive && frame !== null && (
        <FrameView driveId={drive.id} driveName={drive.name} frame={frame} onClose={() => setLarge(false)} />
      )}
      <MineMap
        key={siteId}
        siteId={siteId}
        onMapClick={clickMap}
        placing={placement.placing}
        tools={
          <>
            <label>
              <input
                type="checkbox"
                data-testid="toggle-closures"
                checked={showClosures}
                onChange={(e) => setShowClosures(e.target.checked)}
              />{" "}
              loop closures ({closures.length})
            </label>
            <label title="Residual arrows drawn this many times their length">
              residuals ×{" "}
              <select
                data-testid="residual-exaggeration"
                value={exaggeration}
                onChange={(e) => setExaggeration(Number(e.target.value))}
              >
                {EXAGGERATIONS.map((f) => (
                  <option key={f} value={f}>
                    {f}
                  </option>
                ))}
              </select>
            </label>
            {editable && (
              <label title="Snap groundings to DXF vertices, points and text labels (a label names the station), else to centrelines">
                <input
                  type="checkbox"
                  data-testid="toggle-snap"
                  checked={snapOn}
                  onChange={(e) => setSnapOn(e.target.checked)}
                />{" "}
                snap
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
              selected={driveId !== null && frame !== null ? { driveId, frame } : null}
              keyframeStride={KEYFRAME_STRIDE}
            />
            <GroundingMarkers
              ctx={c}
              groundings={joined}
              poses={poseAt}
              editable={editable}
              selectedId={selectedGrounding?.id ?? null}
              exaggeration={exaggeration}
              onMove={(id, x, y) => void moveGrounding(id, x, y)}
            />
          </>
        )}
      />
      <aside className="side" data-testid="grounding-panel">
        <BuildMap siteId={siteId} version={version} editable={editable} onBuilt={loadVersion} onError={setMessage} />
        <MapExport siteId={siteId} versions={versions} drives={drives.map((d) => d.name)} />
        <CompareVersions siteId={siteId} versions={versions} ctx={ctx} />
        <KeyframeStrip
          drives={drives}
          driveId={driveId}
          onDrive={(id) => {
            setDriveId(id);
            setFrame(null);
            setPage(0);
          }}
          frames={stripFrames}
          frame={frame}
          onFrame={show}
          page={page}
          pageCount={pageCount}
          onPage={setPage}
          playing={playing}
          onPlay={() => setPlaying((p) => !p)}
          onLarge={() => setLarge(true)}
          editable={editable}
          grounded={groundedFrames}
        />
        {editable && frame !== null && (
          <PlacingPanel
            placement={placement}
            frame={frame}
            stationUnder={stationUnder}
            grounding={selectedGrounding}
            onDelete={(id) => void edits.remove(id)}
          />
        )}
        {message && <p data-testid="grounding-message">{message}</p>}
        <div className="row">
          <h3 style={{ margin: 0 }}>Groundings ({groundings.length})</h3>
          <span className="spacer" />
          <GroundingsCsv
            drive={drive}
            editable={editable}
            say={setMessage}
            onImported={async (replaced) => {
              if (replaced) edits.reset();
              await loadGroundings();
            }}
          />
          {editable && (
            <button
              data-testid="undo"
              onClick={() => void edits.undo()}
              disabled={!edits.canUndo}
              title="Undo (u or Ctrl+Z)"
            >
              Undo
            </button>
          )}
          {editable && (
            <button
              data-testid="redo"
              onClick={() => void edits.redo()}
              disabled={!edits.canRedo}
              title="Redo (r or Ctrl+Y)"
            >
              Redo
            </button>
          )}
        </div>
        <ResidualSummary summary={summary} drives={drives} driveId={tableDrive} onDrive={setTableDrive} />
        <GroundingsTable
          rows={rows}
          sort={sort}
          onSort={setSort}
          editable={editable}
          selectedId={selectedGrounding?.id ?? null}
          onOpen={openRow}
          onDelete={(id) => void edits.remove(id)}
          onEnable={(id, enabled) => void setEnabled(id, enabled)}
        />
        <p className="muted">
          Press{" "}
          <button onClick={() => setHelp(true)} data-testid="help">
            ?
          </button>{" "}
          for keyboard shortcuts
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

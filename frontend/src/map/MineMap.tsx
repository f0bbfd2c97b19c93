// The plan view every page shares: survey layers (WebGL when available) with their text labels (scaled with the
// zoom, decluttered), pan/zoom, the pointer's readout (plan
// metres; with the site's coordinates the mine grid and longitude/latitude too), scale bar, fit-to-site. Pages add their own layers through ``overlay``, which gets the map and the local origin.
import { useEffect, useRef, useState, type ReactNode } from "react";
import { useLatest } from "../lib/useLatest";
import OlMap from "ol/Map";
import View from "ol/View";
import VectorSource from "ol/source/Vector";
import VectorLayer from "ol/layer/Vector";
import VectorImageLayer from "ol/layer/VectorImage";
import WebGLVectorLayer from "ol/layer/WebGLVector";
import ScaleLine from "ol/control/ScaleLine";
import { defaults as defaultControls } from "ol/control/defaults";
import { Fill, Stroke, Style, Text } from "ol/style";
import Point from "ol/geom/Point";
import type BaseLayer from "ol/layer/Base";
import type { Geometry } from "ol/geom";
import Feature from "ol/Feature";
import MultiLineString from "ol/geom/MultiLineString";
import { apiGet, ApiError } from "../api/client";
import { LocalOrigin, type Extent } from "../lib/localOrigin";
import { snapTargetsOf, type SnapTargets } from "../lib/snap";
import { wallRingsOf, type WallRings } from "../lib/placement";
import { serverZoomFor } from "../lib/surveyZoom";
import { mark } from "../lib/perf";
import { flattenLines } from "../lib/surveyLines";
import { labelFontPx, labelsOf } from "../lib/surveyLabels";
import { chooseSurveyRenderer, webglRenderer } from "../lib/surveyRenderer";
import { mineGrid } from "./projection";
import { useSiteCoordinates } from "./siteCrs";
import { PointReadout } from "./PointReadout";

export interface MapCtx {
  map: OlMap;
  origin: LocalOrigin;
  siteExtent: Extent | null;
  /** The plan's vertices and centreline segments for snapping (world coordinates; refined with the zoom). */
  snap: { current: SnapTargets | null };
  /** The plan's closed wall outlines (layers named like "wall"; world coordinates), empty without any. */
  walls: { current: WallRings | null };
}

const LAYER_COLOURS = ["#8ca3ba", "#f0b429", "#4dabf7", "#b197fc", "#63e6be", "#ffa8a8", "#d8f5a2"];

interface Props {
  siteId: number;
  overlay?: (ctx: MapCtx) => ReactNode;
  onMapClick?: (x: number, y: number) => void;
  tools?: ReactNode;
  /** A placing mode is on: a crosshair over the plan. */
  placing?: boolean;
}

interface SurveyLayer {
  name: string;
  layer: BaseLayer;
  /** The layer's text labels, when it has any; shown and hidden with it. */
  labels: BaseLayer | null;
  labelCount: number;
  features: number;
}

/** A plan label's style at ``resolution`` (metres per pixel): its lettering scaled with the zoom. */
function labelStyle(colour: string): (feature: unknown, resolution: number) => Style | undefined {
  const cache = new Map<string, Style>();
  return (feature, resolution) => {
    const px = labelFontPx(resolution, (feature as Feature).get("heightM") as number);
    if (px === null) return undefined;
    const text = (feature as Feature).get("text") as string;
    const key = `${px}|${text}`;
    let style = cache.get(key);
    if (!style) {
      style = new Style({
        text: new Text({
          text,
          font: `${px}px system-ui, sans-serif`,
          fill: new Fill({ color: colour }),
          stroke: new Stroke({ color: "#0b0e12", width: 3 }),
          overflow: true,
        }),
      });
      cache.set(key, style);
    }
    return style;
  };
}

export function MineMap({ siteId, overlay, onMapClick, tools, placing }: Props) {
  const target = useRef<HTMLDivElement>(null);
  const [ctx, setCtx] = useState<MapCtx | null>(null);
  const [layers, setLayers] = useState<SurveyLayer[]>([]);
  const [visible, setVisible] = useState<Record<string, boolean>>({});
  const [pointer, setPointer] = useState<[number, number] | null>(null);
  const coords = useSiteCoordinates(siteId);
  const [error, setError] = useState<string | null>(null);
  const [renderer] = useState(() =>
    chooseSurveyRenderer(webglRenderer(), new URLSearchParams(location.search).get("renderer")),
  );
  const clickRef = useLatest(onMapClick);
  // When the map became clickable (performance.now()): OpenLayers fires a click ~250 ms late (it waits to rule
  // out a double click), so a click made before a mode began must not land in the mode.
  const clickableSince = useRef(0);
  const clickable = onMapClick !== undefined;
  useEffect(() => {
    if (clickable) clickableSince.current = performance.now();
  }, [clickable]);
  const originRef = useLatest<LocalOrigin | null>(ctx?.origin ?? null);

  useEffect(() => {
    if (!target.current) return;
    let cancelled = false;
    const map = new OlMap({
      target: target.current,
      controls: defaultControls({ attribution: false, rotate: false }).extend([new ScaleLine({ units: "metric" })]),
      view: new View({ projection: mineGrid, center: [0, 0], zoom: 2 }),
    });
    const added: BaseLayer[] = [];
    const snap: { current: SnapTargets | null } = { current: null };
    const walls: { current: WallRings | null } = { current: null };
    const isCentreline = (name: string) => /centre|center/i.test(name);
    const isWall = (name: string) => /wall/i.test(name);
    const fetchLayers = (zoom: number) => apiGet("/api/sites/{site_id}/survey/layers", { site_id: siteId }, { zoom });
    void (async () => {
      let origin = new LocalOrigin(0, 0);
      let siteExtent: Extent | null = null;
      try {
        // a coarse plan first (its extents place the origin and the view), then the detail the view needs
        const survey = await fetchLayers(0);
        if (cancelled) return;
        origin = LocalOrigin.ofExtent(survey.extents);
        siteExtent = origin.localExtent(survey.extents);
        const [minX, minY, maxX, maxY] = survey.extents as [number, number, number, number];
        const sideM = Math.max(maxX - minX, maxY - minY);
        snap.current = snapTargetsOf(survey.layers, isCentreline);
        walls.current = wallRingsOf(survey.layers, isWall);
        // one multi-line feature per layer (see lib/surveyLines.ts), shifted to the local origin
        const read = (collection: unknown, o: LocalOrigin): Feature<Geometry>[] => {
          const lines = flattenLines(collection, o.x0, o.y0);
          return lines.ends.length > 0 ? [new Feature(new MultiLineString(lines.flat, "XY", lines.ends))] : [];
        };
        const countOf = (collection: unknown) => (collection as { features?: unknown[] }).features?.length ?? 0;
        const sources = new Map<string, VectorSource>();
        const made: SurveyLayer[] = [];
        Object.entries(survey.layers).forEach(([name, collection], i) => {
          const features = read(collection, origin);
          const source = new VectorSource({ features });
          sources.set(name, source);
          const colour = LAYER_COLOURS[i % LAYER_COLOURS.length]!;
          const stroke = new Style({ stroke: new Stroke({ color: colour, width: 1.5 }) });
          const layer =
            renderer === "webgl"
              ? new WebGLVectorLayer({ source, style: { "stroke-color": colour, "stroke-width": 1.5 } })
              : renderer === "image"
                ? new VectorImageLayer({ source, style: stroke, imageRatio: 1.5 })
                : new VectorLayer({ source, style: stroke });
          layer.set("surveyLayer", name);
          map.addLayer(layer);
          added.push(layer);
          const texts = labelsOf(collection, origin.x0, origin.y0);
          let labels: VectorLayer | null = null;
          if (texts.length > 0) {
            const labelFeatures = texts.map(
              (t) => new Feature({ geometry: new Point([t.x, t.y]), text: t.text, heightM: t.heightM }),
            );
            labels = new VectorLayer({
              source: new VectorSource({ features: labelFeatures }),
              style: labelStyle(colour),
              declutter: true,
              zIndex: 5,
            });
            labels.set("surveyLabels", name);
            map.addLayer(labels);
            added.push(labels);
          }
          made.push({ name, layer, labels, labelCount: texts.length, features: countOf(collection) });
        });
        setLayers(made);
        setVisible(Object.fromEntries(made.map((l) => [l.name, true])));
        let loadedZoom = 0;
        let generation = 0;
        const o = origin;
        const refine = async () => {
          const zoom = serverZoomFor(sideM, map.getView().getResolution() ?? 0);
          if (cancelled || zoom <= loadedZoom) return;
          loadedZoom = zoom;
          const mine = ++generation;
          try {
            const detail = await fetchLayers(zoom);
            if (cancelled || mine !== generation) return;
            for (const [name, collection] of Object.entries(detail.layers)) {
              const source = sources.get(name);
              if (!source) continue;
              source.clear(true);
              source.addFeatures(read(collection, o));
            }
            snap.current = snapTargetsOf(detail.layers, isCentreline);
            walls.current = wallRingsOf(detail.layers, isWall);
            map.once("rendercomplete", () => mark("survey-detail"));
          } catch {
            if (mine === generation) loadedZoom = 0; // try again on the next move
          }
        };
        map.once("rendercomplete", () => mark("survey-coarse"));
        map.on("moveend", () => void refine());
        map.getView().fit(siteExtent, { padding: [40, 40, 40, 40] });
      } catch (e) {
        if (cancelled) return;
        setError(e instanceof ApiError && e.status === 404 ? "this site has no survey plan yet" : String(e));
      }
      setCtx({ map, origin, siteExtent, snap, walls });
    })();
    map.on("pointermove", (ev) => {
      const o = originRef.current;
      if (!o) return;
      const [x, y] = o.toWorld(ev.coordinate[0]!, ev.coordinate[1]!);
      setPointer([x, y]);
    });
    map.on("singleclick", (ev) => {
      const o = originRef.current;
      if (!o || !clickRef.current || ev.originalEvent.timeStamp < clickableSince.current) return;
      const [x, y] = o.toWorld(ev.coordinate[0]!, ev.coordinate[1]!);
      clickRef.current(x, y);
    });
    return () => {
      cancelled = true;
      for (const layer of added) map.removeLayer(layer);
      map.setTarget(undefined);
      map.dispose();
      setCtx(null);
      setLayers([]);
    };
  }, [siteId, renderer, clickRef, originRef]);

  useEffect(() => {
    for (const l of layers) {
      l.layer.setVisible(visible[l.name] ?? true);
      l.labels?.setVisible(visible[l.name] ?? true);
    }
  }, [layers, visible]);

  const fit = () => {
    if (ctx?.siteExtent) ctx.map.getView().fit(ctx.siteExtent, { padding: [40, 40, 40, 40], duration: 300 });
  };

  return (
    <div className={placing ? "mapwrap placing" : "mapwrap"}>
      <div
        className="map"
        ref={target}
        data-testid="map"
        data-ready={ctx ? "yes" : "no"}
        data-renderer={renderer}
        data-placing={placing ? "yes" : "no"}
        data-labels={layers.reduce((n, l) => n + l.labelCount, 0)}
      />
      {layers.length > 0 && (
        <div className="overlay-box layers" data-testid="layer-panel">
          {layers.map((l) => (
            <label key={l.name}>
              <input
                type="checkbox"
                data-testid={`layer-toggle-${l.name}`}
                checked={visible[l.name] ?? true}
                onChange={(e) => setVisible({ ...visible, [l.name]: e.target.checked })}
              />{" "}
              {l.name} <span className="muted">({l.features})</span>
            </label>
          ))}
        </div>
      )}
      <div className="overlay-box maptools">
        {tools}
        <button data-testid="fit-site" onClick={fit} title="Fit the whole site">
          Fit site
        </button>
      </div>
      <div className="overlay-box readout" data-testid="grid-readout">
        {error ? (
          <span className="error">{error}</span>
        ) : pointer ? (
          <PointReadout x={pointer[0]} y={pointer[1]} coords={coords} />
        ) : (
          "mine grid (m)"
        )}
      </div>
      {ctx && overlay?.(ctx)}
    </div>
  );
}

// Groundings on the plan: a square at each surveyed point with a line to its keyframe's optimised pose (the
// residual vector). When editable, a square can be dragged to adjust its surveyed point: ``onMove`` gets the
// grounding's id and its new position in mine-grid metres once the drag ends.
import { useEffect, useRef } from "react";
import { useLatest } from "../lib/useLatest";
import Feature from "ol/Feature";
import LineString from "ol/geom/LineString";
import Point from "ol/geom/Point";
import Translate from "ol/interaction/Translate";
import VectorLayer from "ol/layer/Vector";
import VectorSource from "ol/source/Vector";
import { Fill, RegularShape, Stroke, Style } from "ol/style";
import type { GroundingRow } from "../lib/residuals";
import type { MapCtx } from "./MineMap";

interface Props {
  ctx: MapCtx;
  groundings: GroundingRow[];
  /** Optimised pose of each keyframe by ``"driveId#frame"``, mine-grid metres. */
  poses: Map<string, [number, number]>;
  editable: boolean;
  /** The selected keyframe's grounding, drawn highlighted. */
  selectedId: number | null;
  onMove: (id: number, x: number, y: number) => void;
}

const SQUARE = new Style({
  image: new RegularShape({
    points: 4,
    radius: 6,
    angle: Math.PI / 4,
    fill: new Fill({ color: "rgba(255,255,255,0.15)" }),
    stroke: new Stroke({ color: "#fff", width: 1.5 }),
  }),
});
const SELECTED_SQUARE = new Style({
  image: new RegularShape({
    points: 4,
    radius: 8,
    angle: Math.PI / 4,
    fill: new Fill({ color: "rgba(77,171,247,0.35)" }),
    stroke: new Stroke({ color: "#4dabf7", width: 2.5 }),
  }),
  zIndex: 1,
});
const LINK = new Style({ stroke: new Stroke({ color: "#fff", width: 1 }) });
const MOVED_EPS_M = 1e-6;

export function GroundingMarkers({ ctx, groundings, poses, editable, selectedId, onMove }: Props) {
  const sources = useRef({ squares: new VectorSource<Feature<Point>>(), links: new VectorSource() });
  const moveRef = useLatest(onMove);

  useEffect(() => {
    const s = sources.current;
    const links = new VectorLayer({ source: s.links, zIndex: 7 });
    const squares = new VectorLayer({ source: s.squares, zIndex: 8 });
    squares.set("groundingMarkers", true);
    ctx.map.addLayer(links);
    ctx.map.addLayer(squares);
    return () => {
      ctx.map.removeLayer(links);
      ctx.map.removeLayer(squares);
    };
  }, [ctx]);

  useEffect(() => {
    if (!editable) return;
    const squaresLayer = ctx.map
      .getLayers()
      .getArray()
      .find((l) => l.get("groundingMarkers") === true);
    if (!(squaresLayer instanceof VectorLayer)) return;
    const translate = new Translate({ layers: [squaresLayer], hitTolerance: 4 });
    translate.on("translating", (e) => {
      for (const f of e.features.getArray()) {
        const link = f.get("link") as Feature<LineString> | undefined;
        const pose = f.get("pose") as number[] | undefined;
        const at = (f.getGeometry() as Point).getCoordinates();
        if (link && pose) link.getGeometry()?.setCoordinates([at, pose]);
      }
    });
    translate.on("translateend", (e) => {
      const moved = Math.hypot(e.coordinate[0]! - e.startCoordinate[0]!, e.coordinate[1]! - e.startCoordinate[1]!);
      if (moved < MOVED_EPS_M) return; // a click, not a drag
      for (const f of e.features.getArray()) {
        const [lx, ly] = (f.getGeometry() as Point).getCoordinates();
        const [x, y] = ctx.origin.toWorld(lx!, ly!);
        moveRef.current(f.get("groundingId") as number, x, y);
      }
    });
    ctx.map.addInteraction(translate);
    const target = ctx.map.getTargetElement();
    const cursor = (ev: { pixel: number[]; dragging: boolean }) => {
      if (ev.dragging || !target) return;
      const over = ctx.map.hasFeatureAtPixel(ev.pixel, { layerFilter: (l) => l === squaresLayer, hitTolerance: 4 });
      target.style.cursor = over ? "move" : "";
    };
    ctx.map.on("pointermove", cursor);
    return () => {
      ctx.map.un("pointermove", cursor);
      ctx.map.removeInteraction(translate);
      if (target) target.style.cursor = "";
    };
  }, [ctx, editable, moveRef]);

  useEffect(() => {
    const { squares, links } = sources.current;
    squares.clear();
    links.clear();
    for (const g of groundings) {
      const at = ctx.origin.toLocal(g.x, g.y);
      const square = new Feature(new Point(at));
      square.setStyle(g.id === selectedId ? SELECTED_SQUARE : SQUARE);
      square.set("groundingId", g.id);
      const pose = poses.get(`${g.driveId}#${g.frame}`);
      if (pose) {
        const local = ctx.origin.toLocal(...pose);
        const link = new Feature(new LineString([at, local]));
        link.setStyle(LINK);
        links.addFeature(link);
        square.set("link", link);
        square.set("pose", local);
      }
      squares.addFeature(square);
    }
  }, [ctx, groundings, poses, selectedId]);

  return null;
}

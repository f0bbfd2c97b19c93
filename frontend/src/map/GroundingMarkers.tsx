// Groundings on the plan: a square at each surveyed point with an arrow towards its keyframe's optimised pose
// (the residual vector, drawn ``exaggeration`` times its length so that centimetres show at mine scale; the map
// element's ``data-longest-arrow-m`` is the longest arrow as drawn, metres). When editable, a square can be
// dragged to adjust its surveyed point: ``onMove`` gets the grounding's id and its new position in mine-grid
// metres once the drag ends.
import { useEffect, useRef } from "react";
import { useLatest } from "../lib/useLatest";
import Feature from "ol/Feature";
import LineString from "ol/geom/LineString";
import Point from "ol/geom/Point";
import Translate from "ol/interaction/Translate";
import VectorLayer from "ol/layer/Vector";
import VectorSource from "ol/source/Vector";
import { Fill, RegularShape, Stroke, Style } from "ol/style";
import { arrowEnd, type GroundingRow } from "../lib/residuals";
import type { MapCtx } from "./MineMap";

interface Props {
  ctx: MapCtx;
  groundings: GroundingRow[];
  /** Optimised pose of each keyframe by ``"driveId#frame"``, mine-grid metres. */
  poses: Map<string, [number, number]>;
  editable: boolean;
  /** The selected keyframe's grounding, drawn highlighted. */
  selectedId: number | null;
  /** The residual arrows are drawn this many times their length (1: to the pose). */
  exaggeration: number;
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
const LINK_STROKE = new Stroke({ color: "#fff", width: 1 });
const HEAD_RADIUS_PX = 4;

/** A residual arrow: the line, and a head at its end pointing away from the surveyed point. */
function arrowStyle(feature: { getGeometry: () => unknown }): Style[] {
  const coords = (feature.getGeometry() as LineString).getCoordinates();
  const [a, b] = [coords[0]!, coords[coords.length - 1]!];
  const styles = [new Style({ stroke: LINK_STROKE })];
  if (Math.hypot(b[0]! - a[0]!, b[1]! - a[1]!) > 0) {
    const angle = Math.atan2(b[1]! - a[1]!, b[0]! - a[0]!);
    styles.push(
      new Style({
        geometry: new Point(b),
        image: new RegularShape({
          points: 3,
          radius: HEAD_RADIUS_PX,
          rotation: Math.PI / 2 - angle,
          fill: new Fill({ color: "#fff" }),
        }),
      }),
    );
  }
  return styles;
}
const MOVED_EPS_M = 1e-6;

export function GroundingMarkers({ ctx, groundings, poses, editable, selectedId, exaggeration, onMove }: Props) {
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
        const factor = f.get("exaggeration") as number;
        const at = (f.getGeometry() as Point).getCoordinates();
        if (link && pose) link.getGeometry()?.setCoordinates([at, arrowEnd(at, pose, factor)]);
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
    let longestM = 0;
    for (const g of groundings) {
      const at = ctx.origin.toLocal(g.x, g.y);
      const square = new Feature(new Point(at));
      square.setStyle(g.id === selectedId ? SELECTED_SQUARE : SQUARE);
      square.set("groundingId", g.id);
      const pose = poses.get(`${g.driveId}#${g.frame}`);
      if (pose) {
        const local = ctx.origin.toLocal(...pose);
        const end = arrowEnd(at, local, exaggeration);
        longestM = Math.max(longestM, Math.hypot(end[0] - at[0], end[1] - at[1]));
        const link = new Feature(new LineString([at, end]));
        link.setStyle(arrowStyle);
        links.addFeature(link);
        square.set("link", link);
        square.set("pose", local);
        square.set("exaggeration", exaggeration);
      }
      squares.addFeature(square);
    }
    const target = ctx.map.getTargetElement();
    if (target) target.dataset.longestArrowM = longestM.toFixed(3);
  }, [ctx, groundings, poses, selectedId, exaggeration]);

  return null;
}

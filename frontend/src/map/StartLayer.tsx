// A vehicle's known start on the plan: the accepted start as a ring of its radius around a cross, and a
// crosshair cursor while the next click on the map places a start.
import { useEffect, useRef } from "react";
import Feature from "ol/Feature";
import CircleGeom from "ol/geom/Circle";
import Point from "ol/geom/Point";
import VectorSource from "ol/source/Vector";
import VectorLayer from "ol/layer/Vector";
import { Fill, RegularShape, Stroke, Style } from "ol/style";
import type { MapCtx } from "./MineMap";

const START_COLOUR = "#4dabf7";

export interface PlacedStart {
  x: number; // survey metres east
  y: number; // survey metres north
  radius_m: number;
}

export function StartLayer({ ctx, start, placing }: { ctx: MapCtx; start: PlacedStart | null; placing: boolean }) {
  const source = useRef(new VectorSource());

  useEffect(() => {
    const layer = new VectorLayer({ source: source.current, zIndex: 9 });
    ctx.map.addLayer(layer);
    return () => {
      ctx.map.removeLayer(layer);
    };
  }, [ctx]);

  useEffect(() => {
    const s = source.current;
    s.clear();
    if (!start) return;
    const centre = ctx.origin.toLocal(start.x, start.y);
    const ring = new Feature(new CircleGeom(centre, start.radius_m));
    ring.setStyle(
      new Style({
        stroke: new Stroke({ color: START_COLOUR, width: 2, lineDash: [6, 4] }),
        fill: new Fill({ color: "rgba(77, 171, 247, 0.08)" }),
      }),
    );
    const cross = new Feature(new Point(centre));
    cross.setStyle(
      new Style({
        image: new RegularShape({
          points: 4,
          radius: 8,
          radius2: 0,
          angle: Math.PI / 4,
          stroke: new Stroke({ color: START_COLOUR, width: 2 }),
        }),
      }),
    );
    s.addFeatures([ring, cross]);
  }, [ctx, start]);

  useEffect(() => {
    const element = ctx.map.getTargetElement();
    if (!element) return;
    element.style.cursor = placing ? "crosshair" : "";
    return () => {
      element.style.cursor = "";
    };
  }, [ctx, placing]);

  return null;
}

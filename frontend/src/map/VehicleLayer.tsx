// Vehicles on the plan: a heading arrow in the confidence colour (grey when stale), the name, a trail of the
// last minutes; markers glide to each new estimate (lib/interpolate.ts) on the animation frame.
import { useEffect, useRef } from "react";
import Feature from "ol/Feature";
import Point from "ol/geom/Point";
import LineString from "ol/geom/LineString";
import VectorSource from "ol/source/Vector";
import VectorLayer from "ol/layer/Vector";
import { Circle, Fill, RegularShape, Stroke, Style, Text } from "ol/style";
import type { FeatureLike } from "ol/Feature";
import { Glide } from "../lib/interpolate";
import { STALE_GREY, confidenceColour, rgbCss } from "../lib/colours";
import type { VehicleState } from "../lib/liveState";
import type { MapCtx } from "./MineMap";

interface Props {
  ctx: MapCtx;
  vehicles: VehicleState[];
  selectedId: number | null;
  onSelect: (id: number) => void;
}

function markerStyle(feature: FeatureLike): Style[] {
  const stale = feature.get("stale") as boolean;
  const colour = rgbCss(stale ? STALE_GREY : confidenceColour(feature.get("confidence") as number));
  const yaw = feature.get("yaw") as number | null;
  const selected = feature.get("selected") as boolean;
  const shape =
    yaw === null
      ? new Circle({ radius: 7, fill: new Fill({ color: colour }), stroke: new Stroke({ color: "#000", width: 1 }) })
      : new RegularShape({
          points: 3,
          radius: 10,
          rotation: Math.PI / 2 - yaw,
          fill: new Fill({ color: colour }),
          stroke: new Stroke({ color: selected ? "#fff" : "#000", width: selected ? 2 : 1 }),
        });
  return [
    new Style({
      zIndex: stale ? 0 : selected ? 2 : 1, // live vehicles over stale ones
      image: shape,
      text: new Text({
        text: feature.get("name") as string,
        offsetY: -18,
        font: "600 12px system-ui, sans-serif",
        fill: new Fill({ color: stale ? "#9aa3ad" : "#e3e8ee" }),
        stroke: new Stroke({ color: "#0b0e12", width: 3 }),
      }),
    }),
  ];
}

function trailStyle(feature: FeatureLike): Style {
  const stale = feature.get("stale") as boolean;
  return new Style({ stroke: new Stroke({ color: stale ? "rgba(120,126,134,0.5)" : "rgba(77,171,247,0.6)", width: 2 }) });
}

export function VehicleLayer({ ctx, vehicles, selectedId, onSelect }: Props) {
  const source = useRef(new VectorSource());
  const glides = useRef(new Map<number, { glide: Glide; marker: Feature<Point>; trail: Feature<LineString> }>());
  const selectRef = useRef(onSelect);
  selectRef.current = onSelect;

  useEffect(() => {
    const layer = new VectorLayer({ source: source.current, zIndex: 10, updateWhileAnimating: true });
    ctx.map.addLayer(layer);
    let frame = 0;
    const tick = () => {
      const now = performance.now();
      for (const { glide, marker } of glides.current.values()) {
        const p = glide.at(now);
        const [x, y] = ctx.origin.toLocal(p.x, p.y);
        marker.getGeometry()!.setCoordinates([x, y]);
        marker.set("yaw", p.yaw, true);
      }
      source.current.changed();
      frame = requestAnimationFrame(tick);
    };
    frame = requestAnimationFrame(tick);
    const click = ctx.map.on("singleclick", (ev) => {
      ctx.map.forEachFeatureAtPixel(
        ev.pixel,
        (f) => {
          const id = f.get("vehicleId") as number | undefined;
          if (id !== undefined && f.getGeometry()?.getType() === "Point") {
            selectRef.current(id);
            return true;
          }
          return false;
        },
        { layerFilter: (l) => l === layer, hitTolerance: 6 },
      );
    });
    return () => {
      cancelAnimationFrame(frame);
      ctx.map.un("singleclick", click.listener);
      ctx.map.removeLayer(layer);
    };
  }, [ctx]);

  useEffect(() => {
    const now = performance.now();
    const seen = new Set<number>();
    for (const v of vehicles) {
      if (!v.position) continue;
      seen.add(v.id);
      const pose = { x: v.position.x, y: v.position.y, yaw: v.position.yaw };
      let entry = glides.current.get(v.id);
      if (!entry) {
        const marker = new Feature(new Point(ctx.origin.toLocal(pose.x, pose.y)));
        marker.setStyle(markerStyle);
        const trail = new Feature(new LineString([]));
        trail.setStyle(trailStyle);
        source.current.addFeatures([trail, marker]);
        entry = { glide: new Glide(pose, now), marker, trail };
        glides.current.set(v.id, entry);
      } else {
        const t = entry.glide.target;
        if (t.x !== pose.x || t.y !== pose.y || t.yaw !== pose.yaw) entry.glide.retarget(pose, now);
      }
      for (const f of [entry.marker, entry.trail]) {
        f.setProperties(
          {
            vehicleId: v.id,
            name: v.name,
            stale: v.stale,
            confidence: v.position.confidence,
            selected: v.id === selectedId,
          },
          true,
        );
      }
      entry.trail.getGeometry()!.setCoordinates(v.trail.map((p) => ctx.origin.toLocal(p.x, p.y)));
    }
    for (const [id, entry] of glides.current) {
      if (!seen.has(id)) {
        source.current.removeFeatures([entry.marker, entry.trail]);
        glides.current.delete(id);
      }
    }
    source.current.changed();
  }, [vehicles, selectedId, ctx]);

  return null;
}

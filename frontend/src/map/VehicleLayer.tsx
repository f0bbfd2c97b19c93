// Vehicles on the plan: the marker in its confidence band (lib/confidence.ts): an arrow along the heading (a dot
// while the heading is unknown), a dashed ring with "?" when lost, grey when stale; the name and the trail of the
// last minutes in the vehicle's own colour (lib/vehicleColours.ts), the trail dashed by the band of each position
// (solid only when confident, grey when stale) and cut where the vehicle jumped (lib/trail.ts). Markers
// glide to each new estimate (lib/interpolate.ts) on the animation frame. Names are decluttered (an overlapped
// name is left out, never the marker; the selected vehicle's name always shows). With ``follow`` the map stays
// centred on that vehicle (the map element's ``data-follow-offset`` says how far off, metres) until the user
// drags the map. The map element's ``data-trail-colours`` lists each drawn trail's colour by vehicle name, and
// ``data-trail-pieces`` how many pieces each vehicle's trail is cut into at its jumps.
import { useEffect, useRef } from "react";
import { useLatest } from "../lib/useLatest";
import Feature from "ol/Feature";
import Point from "ol/geom/Point";
import LineString from "ol/geom/LineString";
import MultiLineString from "ol/geom/MultiLineString";
import VectorSource from "ol/source/Vector";
import VectorLayer from "ol/layer/Vector";
import { Circle, Fill, Icon, Stroke, Style, Text } from "ol/style";
import type { FeatureLike } from "ol/Feature";
import type ImageStyle from "ol/style/Image";
import { Glide } from "../lib/interpolate";
import { bandCss, confidenceBand, type ConfidenceBand } from "../lib/confidence";
import { yawToRotation } from "../lib/motion";
import { isJump, splitJumps, trailRuns } from "../lib/trail";
import { trailStroke, vehicleCss } from "../lib/vehicleColours";
import type { VehicleState } from "../lib/liveState";
import type { MapCtx } from "./MineMap";

interface Props {
  ctx: MapCtx;
  vehicles: VehicleState[];
  selectedId: number | null;
  onSelect: (id: number) => void;
  /** Whether a click on a marker selects its vehicle (off while a click means something else). */
  selectable: boolean;
  /** The vehicle the map stays centred on, or null. */
  follow: number | null;
  /** The user dragged the map: following ends. */
  onFollowEnd: () => void;
}

const ARROW_PX = 26; // drawn size on screen
const arrows = new Map<string, HTMLCanvasElement>();

/** An arrow pointing up (north before rotation), drawn at twice the screen size for sharp edges. */
function arrowCanvas(fill: string, outline: string, outlineWidth: number): HTMLCanvasElement {
  const key = `${fill}|${outline}|${outlineWidth}`;
  let canvas = arrows.get(key);
  if (!canvas) {
    const s = ARROW_PX * 2;
    canvas = document.createElement("canvas");
    canvas.width = s;
    canvas.height = s;
    const g = canvas.getContext("2d")!;
    g.beginPath();
    g.moveTo(s * 0.5, s * 0.06);
    g.lineTo(s * 0.86, s * 0.9);
    g.lineTo(s * 0.5, s * 0.7);
    g.lineTo(s * 0.14, s * 0.9);
    g.closePath();
    g.fillStyle = fill;
    g.fill();
    g.lineJoin = "round";
    g.lineWidth = outlineWidth * 2;
    g.strokeStyle = outline;
    g.stroke();
    arrows.set(key, canvas);
  }
  return canvas;
}

function markerImage(band: ConfidenceBand, yaw: number | null, selected: boolean): ImageStyle {
  const colour = bandCss(band);
  const outline = selected ? "#fff" : "#000";
  const width = selected ? 2 : 1;
  if (band === "lost") {
    return new Circle({
      radius: 10,
      fill: new Fill({ color: "rgba(214, 51, 168, 0.25)" }),
      stroke: new Stroke({ color: colour, width: 3, lineDash: [4, 3] }),
      declutterMode: "obstacle",
    });
  }
  if (yaw === null) {
    return new Circle({
      radius: 7,
      fill: new Fill({ color: colour }),
      stroke: new Stroke({ color: outline, width }),
      declutterMode: "obstacle",
    });
  }
  return new Icon({
    img: arrowCanvas(colour, outline, width),
    scale: 0.5,
    rotation: yawToRotation(yaw),
    rotateWithView: true,
    declutterMode: "obstacle",
  });
}

/** A vehicle marker and its name: the marker an obstacle to other names, an unselected name decluttered (hidden
 * where it would overlap another name or a marker), the selected one always drawn. */
export function markerStyle(feature: FeatureLike): Style[] {
  const band = feature.get("band") as ConfidenceBand;
  const yaw = feature.get("yaw") as number | null;
  const selected = feature.get("selected") as boolean;
  const stale = band === "stale";
  const styles = [
    new Style({
      zIndex: stale ? 0 : selected ? 2 : 1, // live vehicles over stale ones
      image: markerImage(band, yaw, selected),
      text: new Text({
        text: feature.get("name") as string,
        offsetY: -20,
        font: "600 12px system-ui, sans-serif",
        fill: new Fill({ color: stale ? "#9aa3ad" : (feature.get("colour") as string) }),
        stroke: new Stroke({ color: "#0b0e12", width: 3 }),
        declutterMode: selected ? "none" : "declutter", // markers are obstacles: a name never covers one
      }),
    }),
  ];
  if (band === "lost") {
    styles.push(
      new Style({
        zIndex: 2,
        text: new Text({
          text: "?",
          font: "700 13px system-ui, sans-serif",
          fill: new Fill({ color: "#fff" }),
          declutterMode: "none",
        }),
      }),
    );
  }
  return styles;
}

/** One style per run of the trail (the vehicle's colour, dashed by band); ``runs`` in local map coordinates. */
function trailStyles(
  vehicleId: number,
  runs: { band: ConfidenceBand; coords: number[][] }[],
  selected: boolean,
): Style[] {
  return runs.map(({ band, coords }) => {
    const { colour, dash } = trailStroke(vehicleId, band);
    return new Style({
      geometry: new LineString(coords),
      stroke: new Stroke({ color: colour, width: selected ? 4 : 2.5, lineDash: dash }),
    });
  });
}

export function VehicleLayer({ ctx, vehicles, selectedId, onSelect, selectable, follow, onFollowEnd }: Props) {
  const source = useRef(new VectorSource());
  const glides = useRef(new Map<number, { glide: Glide; marker: Feature<Point>; trail: Feature<MultiLineString> }>());
  const selectRef = useLatest(onSelect);
  const selectableRef = useLatest(selectable);
  const followRef = useLatest(follow);
  const followEndRef = useLatest(onFollowEnd);

  useEffect(() => {
    const layer = new VectorLayer({
      source: source.current,
      zIndex: 10,
      updateWhileAnimating: true,
      updateWhileInteracting: true,
      declutter: true,
    });
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
      const target = ctx.map.getTargetElement();
      const followed = followRef.current === null ? undefined : glides.current.get(followRef.current);
      if (followed) {
        const at = followed.marker.getGeometry()!.getCoordinates();
        const view = ctx.map.getView();
        const centre = view.getCenter();
        if (!centre || centre[0] !== at[0] || centre[1] !== at[1]) view.setCenter(at);
        const now = view.getCenter()!;
        if (target) target.dataset.followOffset = Math.hypot(now[0]! - at[0]!, now[1]! - at[1]!).toFixed(2);
      } else if (target) delete target.dataset.followOffset;
      source.current.changed();
      frame = requestAnimationFrame(tick);
    };
    frame = requestAnimationFrame(tick);
    const click = ctx.map.on("singleclick", (ev) => {
      if (!selectableRef.current) return;
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
    const drag = ctx.map.on("pointerdrag", () => {
      if (followRef.current !== null) followEndRef.current();
    });
    return () => {
      cancelAnimationFrame(frame);
      ctx.map.un("singleclick", click.listener);
      ctx.map.un("pointerdrag", drag.listener);
      ctx.map.removeLayer(layer);
    };
  }, [ctx, selectRef, selectableRef, followRef, followEndRef]);

  useEffect(() => {
    const now = performance.now();
    const seen = new Set<number>();
    const trailColours: Record<string, string> = {};
    const trailPieces: Record<string, number> = {};
    for (const v of vehicles) {
      if (!v.position) continue;
      seen.add(v.id);
      const pose = { x: v.position.x, y: v.position.y, yaw: v.position.yaw };
      let entry = glides.current.get(v.id);
      if (!entry) {
        const marker = new Feature(new Point(ctx.origin.toLocal(pose.x, pose.y)));
        marker.setStyle(markerStyle);
        const trail = new Feature(new MultiLineString([]));
        source.current.addFeatures([trail, marker]);
        entry = { glide: new Glide(pose, now), marker, trail };
        glides.current.set(v.id, entry);
      } else {
        const t = entry.glide.target;
        const n = v.trail.length;
        if (t.x !== pose.x || t.y !== pose.y || t.yaw !== pose.yaw) {
          const jumped = n >= 2 && isJump(v.trail[n - 2]!, v.trail[n - 1]!);
          if (jumped)
            entry.glide = new Glide(pose, now); // a jump is drawn as one: no glide through rock
          else entry.glide.retarget(pose, now);
        }
      }
      const selected = v.id === selectedId;
      entry.marker.setProperties(
        {
          vehicleId: v.id,
          name: v.name,
          colour: vehicleCss(v.id),
          band: confidenceBand(v.position.confidence, v.position.lost, v.stale),
          selected,
        },
        true,
      );
      const runs = trailRuns(v.trail, v.stale).map((run) => ({
        band: run.band,
        coords: run.points.map((p) => ctx.origin.toLocal(p.x, p.y)),
      }));
      entry.trail.getGeometry()!.setCoordinates(runs.map((r) => r.coords));
      entry.trail.setProperties({ vehicleId: v.id, points: v.trail.length }, true);
      entry.trail.setStyle(trailStyles(v.id, runs, selected));
      if (runs.length > 0) trailColours[v.name] = trailStroke(v.id, runs[runs.length - 1]!.band).colour;
      trailPieces[v.name] = splitJumps(v.trail).length;
    }
    const target = ctx.map.getTargetElement();
    if (target) {
      target.dataset.trailColours = JSON.stringify(trailColours);
      target.dataset.trailPieces = JSON.stringify(trailPieces);
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

// The optimised trajectories of a map version: a line and keyframe points per drive (drive colours), loop
// closures as links (toggle), the selected frame ringed. Groundings are drawn by GroundingMarkers.
import { useEffect, useRef } from "react";
import Feature from "ol/Feature";
import LineString from "ol/geom/LineString";
import MultiPoint from "ol/geom/MultiPoint";
import Point from "ol/geom/Point";
import VectorSource from "ol/source/Vector";
import VectorLayer from "ol/layer/Vector";
import { Circle, Fill, Stroke, Style } from "ol/style";
import { driveColour, rgbCss } from "../lib/colours";
import type { MapCtx } from "./MineMap";

export interface Poses {
  drive_id: number[];
  frame: number[];
  x_m: number[];
  y_m: number[];
}

export interface Closure {
  drive_a: number;
  frame_a: number;
  drive_b: number;
  frame_b: number;
  accepted: boolean;
}

interface Props {
  ctx: MapCtx;
  poses: Poses | null;
  closures: Closure[];
  showClosures: boolean;
  selected: { driveId: number; frame: number } | null;
  keyframeStride: number;
}

export function poseIndex(poses: Poses): Map<string, [number, number]> {
  const index = new Map<string, [number, number]>();
  poses.frame.forEach((f, i) => index.set(`${poses.drive_id[i]}#${f}`, [poses.x_m[i]!, poses.y_m[i]!]));
  return index;
}

export function TrajectoryLayer({ ctx, poses, closures, showClosures, selected, keyframeStride }: Props) {
  const sources = useRef({ tracks: new VectorSource(), closures: new VectorSource(), selected: new VectorSource() });

  useEffect(() => {
    const s = sources.current;
    const layers = [
      new VectorLayer({ source: s.tracks, zIndex: 5 }),
      new VectorLayer({ source: s.closures, zIndex: 6 }),
      new VectorLayer({ source: s.selected, zIndex: 7 }),
    ];
    layers.forEach((l) => ctx.map.addLayer(l));
    return () => layers.forEach((l) => ctx.map.removeLayer(l));
  }, [ctx]);

  useEffect(() => {
    const s = sources.current.tracks;
    s.clear();
    if (!poses) return;
    const byDrive = new Map<number, number[][]>();
    poses.frame.forEach((_, i) => {
      const d = poses.drive_id[i]!;
      const list = byDrive.get(d) ?? [];
      list.push(ctx.origin.toLocal(poses.x_m[i]!, poses.y_m[i]!));
      byDrive.set(d, list);
    });
    for (const [driveId, coords] of byDrive) {
      const colour = rgbCss(driveColour(driveId));
      const line = new Feature(new LineString(coords));
      line.setStyle(new Style({ stroke: new Stroke({ color: colour, width: 2 }) }));
      const points = new Feature(new MultiPoint(coords.filter((_, i) => i % keyframeStride === 0)));
      points.setStyle(new Style({ image: new Circle({ radius: 2.5, fill: new Fill({ color: colour }) }) }));
      s.addFeatures([line, points]);
    }
  }, [ctx, poses, keyframeStride]);

  useEffect(() => {
    const s = sources.current.closures;
    s.clear();
    if (!poses || !showClosures) return;
    const index = poseIndex(poses);
    for (const c of closures) {
      const a = index.get(`${c.drive_a}#${c.frame_a}`);
      const b = index.get(`${c.drive_b}#${c.frame_b}`);
      if (!a || !b) continue;
      const f = new Feature(new LineString([ctx.origin.toLocal(...a), ctx.origin.toLocal(...b)]));
      f.setStyle(
        new Style({
          stroke: new Stroke({ color: c.accepted ? "#63e6be" : "#e5484d", width: 1.5, lineDash: [4, 3] }),
        }),
      );
      s.addFeature(f);
    }
  }, [ctx, poses, closures, showClosures]);

  useEffect(() => {
    const s = sources.current.selected;
    s.clear();
    if (!poses || !selected) return;
    const pose = poseIndex(poses).get(`${selected.driveId}#${selected.frame}`);
    if (!pose) return;
    const ring = new Feature(new Point(ctx.origin.toLocal(...pose)));
    ring.setStyle(new Style({ image: new Circle({ radius: 9, stroke: new Stroke({ color: "#ffd43b", width: 3 }) }) }));
    s.addFeature(ring);
  }, [ctx, poses, selected]);

  return null;
}

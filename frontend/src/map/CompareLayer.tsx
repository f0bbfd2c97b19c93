// Two map versions as an overlay: version A's trajectories thin and grey, version B's dashed in amber over them,
// and a link from each frame's A position to its B position where it moved by at least ``minLinkM``.
import { useEffect, useRef } from "react";
import Feature from "ol/Feature";
import LineString from "ol/geom/LineString";
import MultiLineString from "ol/geom/MultiLineString";
import VectorLayer from "ol/layer/Vector";
import VectorSource from "ol/source/Vector";
import { Stroke, Style } from "ol/style";
import { linksToDraw, tracksByDrive, type Displacement, type PoseArrays } from "../lib/compare";
import type { MapCtx } from "./MineMap";

interface Props {
  ctx: MapCtx;
  a: PoseArrays;
  b: PoseArrays;
  moved: Displacement[];
  minLinkM?: number;
  maxLinks?: number;
}

const A_STYLE = new Style({ stroke: new Stroke({ color: "rgba(200, 208, 218, 0.9)", width: 3 }) });
const B_STYLE = new Style({ stroke: new Stroke({ color: "#ffd43b", width: 2, lineDash: [6, 4] }) });
const LINK_STYLE = new Style({ stroke: new Stroke({ color: "#ff6b6b", width: 1.5 }) });

export function CompareLayer({ ctx, a, b, moved, minLinkM = 0.5, maxLinks = 500 }: Props) {
  const source = useRef(new VectorSource());

  useEffect(() => {
    const layer = new VectorLayer({ source: source.current, zIndex: 9 });
    layer.set("compareOverlay", true);
    ctx.map.addLayer(layer);
    return () => {
      ctx.map.removeLayer(layer);
    };
  }, [ctx]);

  useEffect(() => {
    const s = source.current;
    s.clear();
    const local = (p: [number, number]) => ctx.origin.toLocal(p[0], p[1]);
    const tracks = (poses: PoseArrays, style: Style, version: "a" | "b") => {
      for (const [driveId, coords] of tracksByDrive(poses)) {
        const f = new Feature(new LineString(coords.map(local)));
        f.setStyle(style);
        f.setProperties({ version, driveId });
        s.addFeature(f);
      }
    };
    tracks(a, A_STYLE, "a");
    tracks(b, B_STYLE, "b");
    const links = linksToDraw(moved, minLinkM, maxLinks);
    if (links.length > 0) {
      const f = new Feature(new MultiLineString(links.map((d) => [local(d.a), local(d.b)])));
      f.setStyle(LINK_STYLE);
      s.addFeature(f);
    }
  }, [ctx, a, b, moved, minLinkM, maxLinks]);

  return null;
}

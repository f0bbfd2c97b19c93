// The replayed vehicle on the plan: its whole loaded track (faint), the last minutes up to the replay time,
// and a violet marker at the interpolated pose; in follow mode the map stays centred on it.
import { useEffect, useRef } from "react";
import Feature from "ol/Feature";
import Point from "ol/geom/Point";
import LineString from "ol/geom/LineString";
import VectorSource from "ol/source/Vector";
import VectorLayer from "ol/layer/Vector";
import { Circle, Fill, RegularShape, Stroke, Style, Text } from "ol/style";
import type { FeatureLike } from "ol/Feature";
import { poseAt, trailUntil } from "../lib/replay";
import type { ReplaySession } from "../views/ReplayPanel";
import type { MapCtx } from "./MineMap";

const REPLAY_COLOUR = "#b197fc";
const TRAIL_S = 180;

function markerStyle(feature: FeatureLike): Style {
  const yaw = feature.get("yaw") as number | null;
  const image =
    yaw === null
      ? new Circle({
          radius: 8,
          fill: new Fill({ color: REPLAY_COLOUR }),
          stroke: new Stroke({ color: "#fff", width: 2 }),
        })
      : new RegularShape({
          points: 3,
          radius: 11,
          rotation: Math.PI / 2 - yaw,
          fill: new Fill({ color: REPLAY_COLOUR }),
          stroke: new Stroke({ color: "#fff", width: 2 }),
        });
  return new Style({
    zIndex: 3,
    image,
    text: new Text({
      text: `${feature.get("name") as string} (replay)`,
      offsetY: -20,
      font: "600 12px system-ui, sans-serif",
      fill: new Fill({ color: REPLAY_COLOUR }),
      stroke: new Stroke({ color: "#0b0e12", width: 3 }),
    }),
  });
}

const trackStyle = new Style({ stroke: new Stroke({ color: "rgba(177,151,252,0.25)", width: 2, lineDash: [4, 4] }) });
const trailStyle = new Style({ stroke: new Stroke({ color: "rgba(177,151,252,0.85)", width: 3 }) });

export function ReplayLayer({ ctx, session }: { ctx: MapCtx; session: ReplaySession }) {
  const source = useRef(new VectorSource());

  useEffect(() => {
    const { track, clock } = session;
    const toLocal = (p: { x: number; y: number }) => ctx.origin.toLocal(p.x, p.y);
    const whole = new Feature(new LineString(track.map(toLocal)));
    whole.setStyle(trackStyle);
    const trail = new Feature(new LineString([]));
    trail.setStyle(trailStyle);
    const marker = new Feature(new Point(toLocal(track[0]!)));
    marker.setStyle(markerStyle);
    marker.set("name", session.name, true);
    source.current.addFeatures([whole, trail, marker]);
    const layer = new VectorLayer({ source: source.current, zIndex: 11, updateWhileAnimating: true });
    ctx.map.addLayer(layer);
    let raf = 0;
    let shownT = Number.NaN;
    const tick = () => {
      const pose = poseAt(track, clock.now);
      if (pose) {
        const at = toLocal(pose);
        if (clock.now !== shownT) {
          shownT = clock.now;
          marker.getGeometry()!.setCoordinates(at);
          marker.set("yaw", pose.yaw, true);
          trail.getGeometry()!.setCoordinates([...trailUntil(track, clock.now, TRAIL_S).map(toLocal), at]);
          source.current.changed();
        }
        const view = ctx.map.getView();
        if (session.follow) {
          const centre = view.getCenter();
          if (!centre || Math.hypot(centre[0]! - at[0], centre[1]! - at[1]) > 1e-3) view.setCenter(at);
          const now = view.getCenter()!;
          session.followOffsetM = Math.hypot(now[0]! - at[0], now[1]! - at[1]);
        }
      }
      raf = requestAnimationFrame(tick);
    };
    raf = requestAnimationFrame(tick);
    const drawn = source.current;
    return () => {
      cancelAnimationFrame(raf);
      ctx.map.removeLayer(layer);
      drawn.clear();
    };
  }, [ctx, session]);

  return null;
}

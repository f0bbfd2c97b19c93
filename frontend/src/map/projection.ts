// The mine grid as an OpenLayers projection: plain metres, y up, no geodesy. Geometries handed to the map are
// already shifted to a local origin (see lib/localOrigin.ts), so the projection's extent is centred on zero.
import Projection from "ol/proj/Projection";
import { addProjection } from "ol/proj";

export const MINE_GRID_CODE = "DRIFTMAP:MINE-LOCAL";
const HALF_SPAN_M = 1_000_000;

export const mineGrid = new Projection({
  code: MINE_GRID_CODE,
  units: "m",
  metersPerUnit: 1,
  extent: [-HALF_SPAN_M, -HALF_SPAN_M, HALF_SPAN_M, HALF_SPAN_M],
  global: false,
});
addProjection(mineGrid);

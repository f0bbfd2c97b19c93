// A plan point as the readouts show it: plane metres, and with the site's coordinates the mine grid (when it is
// not the plane) and longitude/latitude (with an EPSG code). One line each.
import { formatGrid } from "../lib/localOrigin";
import { siteReadout, type SiteCoordinates } from "../lib/siteCoordinates";

interface Props {
  x: number;
  y: number;
  coords: SiteCoordinates | null;
  digits?: number;
  /** Prefix of the lines' test ids: ``{testId}-grid``, ``{testId}-lonlat``. */
  testId?: string;
}

export function PointReadout({ x, y, coords, digits = 2, testId = "pointer" }: Props) {
  const { grid, lonLat, lonLatDeg } = siteReadout(coords, x, y);
  const plan = coords && !coords.identity;
  return (
    <>
      <div title={plan ? "Site plan metres" : undefined}>
        {plan ? "plan " : ""}
        {formatGrid(x, y, digits)}
      </div>
      {grid && (
        <div data-testid={`${testId}-grid`} title="Mine grid metres">
          {grid}
        </div>
      )}
      {lonLat && lonLatDeg && (
        <div
          data-testid={`${testId}-lonlat`}
          data-lon={lonLatDeg[0].toFixed(6)}
          data-lat={lonLatDeg[1].toFixed(6)}
          title={`WGS84 longitude, latitude (from EPSG:${coords?.epsg ?? "?"})`}
        >
          {lonLat}
        </div>
      )}
    </>
  );
}

import { describe, expect, it } from "vitest";
import {
  CLEAR_CRS,
  crsBodyOf,
  crsFormOf,
  formatLonLat,
  refusedField,
  siteCoordinatesOf,
  siteReadout,
  type SiteCrs,
} from "./siteCoordinates";

const UTM55S = "+proj=utm +zone=55 +south +ellps=GRS80 +units=m +no_defs";
const plain = { false_easting_m: 0, false_northing_m: 0, rotation_deg: 0, scale: 1 };

describe("siteCoordinatesOf", () => {
  it("is null without coordinates", () => {
    expect(siteCoordinatesOf(null)).toBeNull();
    expect(siteCoordinatesOf(undefined)).toBeNull();
  });

  it("puts the UTM 55 south central meridian's equator point at 147 E, 0", () => {
    const crs: SiteCrs = { epsg: 28355, ...plain, proj4: UTM55S };
    const c = siteCoordinatesOf(crs)!;
    expect(c.identity).toBe(true);
    const [lon, lat] = c.toLonLat!(500_000, 10_000_000);
    expect(lon).toBeCloseTo(147, 9);
    expect(lat).toBeCloseTo(0, 9);
  });

  it("places a false origin as pyproj does (EPSG:28355, 321000 E 6123000 N)", () => {
    const crs: SiteCrs = {
      epsg: 28355,
      ...plain,
      false_easting_m: 321_000,
      false_northing_m: 6_123_000,
      proj4: `${UTM55S} +type=crs`, // as the server sends it
    };
    const c = siteCoordinatesOf(crs)!;
    expect(c.identity).toBe(false);
    // pyproj: SiteCrs(epsg=28355, false_easting_m=321000, false_northing_m=6123000).to_wgs84([[0, 0], [100, 50]])
    const [lon0, lat0] = c.toLonLat!(0, 0);
    expect(lon0).toBeCloseTo(145.03805054, 7);
    expect(lat0).toBeCloseTo(-35.01981869, 7);
    const [lon1, lat1] = c.toLonLat!(100, 50);
    expect(lon1).toBeCloseTo(145.03915679, 7);
    expect(lat1).toBeCloseTo(-35.01938579, 7);
  });

  it("rotates counter-clockwise, scales and shifts (by hand)", () => {
    // r = 30 deg: x cos r - y sin r = 10 * 0.8660254 - 20 * 0.5 = -1.3397460, x sin r + y cos r = 22.3205081
    const c = siteCoordinatesOf({
      ...plain,
      false_easting_m: 1000,
      false_northing_m: 2000,
      rotation_deg: 30,
      scale: 1.5,
    })!;
    const [e, n] = c.toGrid(10, 20);
    expect(e).toBeCloseTo(1000 + 1.5 * -1.339746, 5);
    expect(n).toBeCloseTo(2000 + 1.5 * 22.3205081, 5);
    expect(c.toLonLat).toBeNull();
    // a quarter turn takes +x to grid north
    const q = siteCoordinatesOf({ ...plain, rotation_deg: 90 })!;
    const [qe, qn] = q.toGrid(1, 0);
    expect(qe).toBeCloseTo(0, 12);
    expect(qn).toBeCloseTo(1, 12);
  });

  it("leaves longitude and latitude out for a PROJ string it cannot read", () => {
    const c = siteCoordinatesOf({ epsg: 1234, ...plain, proj4: "+proj=nonsense" })!;
    expect(c.toLonLat).toBeNull();
  });
});

describe("readout", () => {
  it("formats longitude then latitude with hemispheres, 6 decimals", () => {
    expect(formatLonLat(145.03805054, -35.01981869)).toBe("145.038051° E  35.019819° S");
    expect(formatLonLat(-3.5, 51.25)).toBe("3.500000° W  51.250000° N");
  });

  it("shows the grid only when it is not the plane, and degrees only with an EPSG code", () => {
    expect(siteReadout(null, 1, 2)).toEqual({});
    expect(siteReadout(siteCoordinatesOf({ ...plain, false_easting_m: 100 }), 1, 2)).toEqual({
      grid: "grid E 101.00  N 2.00",
    });
    const utm = siteReadout(siteCoordinatesOf({ epsg: 28355, ...plain, proj4: UTM55S }), 500_000, 10_000_000);
    expect(utm).toMatchObject({ lonLat: "147.000000° E  0.000000° N" });
    expect(utm.grid).toBeUndefined();
    expect(utm.lonLatDeg![0]).toBeCloseTo(147, 9);
  });
});

describe("the settings form", () => {
  it("shows a site's values, and the defaults without any", () => {
    expect(crsFormOf(null)).toEqual({
      epsg: "",
      false_easting_m: "0",
      false_northing_m: "0",
      rotation_deg: "0",
      scale: "1",
    });
    expect(crsFormOf({ epsg: 28355, ...plain, false_easting_m: 321000.5, proj4: UTM55S }).false_easting_m).toBe(
      "321000.5",
    );
  });

  it("builds the PUT body: empty EPSG is none, empty numbers their defaults", () => {
    const form = {
      epsg: " 28355 ",
      false_easting_m: "321000",
      false_northing_m: "6123000",
      rotation_deg: "",
      scale: "",
    };
    expect(crsBodyOf(form)).toEqual({
      body: { epsg: 28355, false_easting_m: 321000, false_northing_m: 6123000, rotation_deg: 0, scale: 1 },
    });
    expect(crsBodyOf(crsFormOf(null))).toEqual({ body: CLEAR_CRS });
    expect(crsBodyOf({ ...form, rotation_deg: "-12.5", scale: "0.9996" })).toMatchObject({
      body: { rotation_deg: -12.5, scale: 0.9996 },
    });
  });

  it("names the fields that are not numbers", () => {
    const form = {
      epsg: "EPSG:28355",
      false_easting_m: "1e3",
      false_northing_m: "north",
      rotation_deg: "0",
      scale: "1",
    };
    const built = crsBodyOf(form);
    expect("errors" in built && Object.keys(built.errors).sort()).toEqual(["epsg", "false_northing_m"]);
    expect("errors" in built && built.errors.epsg).toContain("whole number");
  });

  it("finds the field a refusal names", () => {
    expect(refusedField("crs.epsg: EPSG:4326 (WGS 84) is not a projected system in metres")).toBe("epsg");
    expect(refusedField("crs.scale must be between 0.5 and 2, got 3")).toBe("scale");
    expect(refusedField("scale: Input should be less than or equal to 2")).toBe("scale");
    expect(refusedField("false_northing_m: Input should be a finite number")).toBe("false_northing_m");
    expect(refusedField("not allowed")).toBeNull();
  });
});

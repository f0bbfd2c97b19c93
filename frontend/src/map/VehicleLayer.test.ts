import { describe, expect, it } from "vitest";
import Feature from "ol/Feature";
import Point from "ol/geom/Point";
import type Text from "ol/style/Text";
import { markerStyle } from "./VehicleLayer";

function vehicle(selected: boolean, band = "confident"): Feature<Point> {
  return new Feature({ geometry: new Point([0, 0]), name: "loc-01", band, yaw: null, selected, colour: "#4cc9f0" });
}

describe("markerStyle", () => {
  it("declutters an unselected vehicle's name and keeps its marker as an obstacle", () => {
    const style = markerStyle(vehicle(false))[0]!;
    expect((style.getText() as Text).getDeclutterMode()).toBe("declutter");
    expect(style.getImage()!.getDeclutterMode()).toBe("obstacle");
  });

  it("always draws the selected vehicle's name", () => {
    const style = markerStyle(vehicle(true))[0]!;
    expect((style.getText() as Text).getText()).toBe("loc-01");
    expect((style.getText() as Text).getDeclutterMode()).toBe("none");
  });

  it("marks a lost vehicle with a question mark that is never hidden", () => {
    const styles = markerStyle(vehicle(false, "lost"));
    expect(styles).toHaveLength(2);
    const mark = styles[1]!.getText() as Text;
    expect(mark.getText()).toBe("?");
    expect(mark.getDeclutterMode()).toBe("none");
  });
});

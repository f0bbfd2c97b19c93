import { describe, expect, it } from "vitest";
import { fileForm, uploadProgressText, videoForm, type VideoUpload } from "./upload";

const video = new File(["v"], "run-3.mp4", { type: "video/mp4" });
const calibration = new File(["{}"], "camera.json", { type: "application/json" });
const base: VideoUpload = { video, calibration: null, profileId: 4, name: "", kind: "mapping" };

describe("uploadProgressText", () => {
  it("says megabytes and percent", () => {
    expect(uploadProgressText(3_200_000, 10_000_000)).toBe("3.2 of 10.0 MB (32%)");
    expect(uploadProgressText(0, 0)).toBe("0.0 of 0.0 MB (0%)");
  });
});

describe("videoForm", () => {
  it("sends the video with a profile, the kind and a name only when given", () => {
    const made = videoForm(base);
    if (!("form" in made)) throw new Error(made.error);
    expect(made.form.get("video")).toBeInstanceOf(File);
    expect(made.form.get("profile")).toBe("4");
    expect(made.form.get("calibration")).toBeNull();
    expect(made.form.get("name")).toBeNull();
    expect(made.form.get("kind")).toBe("mapping");
  });

  it("sends a calibration file and a trimmed name instead", () => {
    const made = videoForm({ ...base, calibration, profileId: null, name: " run 3 ", kind: "localisation" });
    if (!("form" in made)) throw new Error(made.error);
    expect((made.form.get("calibration") as File).name).toBe("camera.json");
    expect(made.form.get("profile")).toBeNull();
    expect(made.form.get("name")).toBe("run 3");
    expect(made.form.get("kind")).toBe("localisation");
  });

  it("wants a video and exactly one of a calibration and a profile", () => {
    expect(videoForm({ ...base, video: null })).toEqual({ error: "choose a video file" });
    const either = { error: "give either a calibration file or a camera profile" };
    expect(videoForm({ ...base, calibration, profileId: 4 })).toEqual(either);
    expect(videoForm({ ...base, calibration: null, profileId: null })).toEqual(either);
  });
});

describe("fileForm", () => {
  it("puts the file in the field 'file', or asks for one", () => {
    const made = fileForm(new File(["0"], "plan.dxf"), "a DXF plan");
    if (!("form" in made)) throw new Error(made.error);
    expect((made.form.get("file") as File).name).toBe("plan.dxf");
    expect(fileForm(null, "a DXF plan")).toEqual({ error: "choose a DXF plan" });
  });
});

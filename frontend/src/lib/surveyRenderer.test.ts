import { describe, expect, it } from "vitest";
import { chooseSurveyRenderer } from "./surveyRenderer";

describe("survey renderer", () => {
  it("uses WebGL on a GPU and an image layer on software GL or without WebGL", () => {
    expect(chooseSurveyRenderer("ANGLE (NVIDIA, NVIDIA GeForce RTX 3060 Direct3D11)")).toBe("webgl");
    expect(
      chooseSurveyRenderer("ANGLE (Google, Vulkan 1.3.0 (SwiftShader Device (Subzero)), SwiftShader driver)"),
    ).toBe("image");
    expect(chooseSurveyRenderer("llvmpipe (LLVM 15.0.6, 256 bits)")).toBe("image");
    expect(chooseSurveyRenderer(null)).toBe("image");
  });

  it("follows a valid override and ignores others", () => {
    expect(chooseSurveyRenderer("SwiftShader", "webgl")).toBe("webgl");
    expect(chooseSurveyRenderer("NVIDIA", "canvas")).toBe("canvas");
    expect(chooseSurveyRenderer("NVIDIA", "vulkan")).toBe("webgl");
  });
});

// How to draw the survey plan. WebGL redraws every segment on every map frame, which a GPU does in no time;
// without one (headless browsers, WebGL emulated in software by SwiftShader or llvmpipe) each redraw of a
// 100,000-segment plan costs hundreds of milliseconds, and the live view's gliding markers redraw the map every
// frame. There the plan is drawn once into an image by canvas (OpenLayers' VectorImage layer) and that image is
// reused until the view changes. ``?renderer=webgl|image|canvas`` in the page URL overrides the choice.

export type SurveyRenderer = "webgl" | "image" | "canvas";

const SOFTWARE_GL = /swiftshader|llvmpipe|softpipe|software|basic render/i;

/**
 * The renderer for a browser whose WebGL renderer string is ``glRenderer`` (null: no WebGL), unless ``override``
 * (e.g. the ``renderer`` URL parameter) names a valid one.
 */
export function chooseSurveyRenderer(glRenderer: string | null, override?: string | null): SurveyRenderer {
  if (override === "webgl" || override === "image" || override === "canvas") return override;
  if (glRenderer === null || SOFTWARE_GL.test(glRenderer)) return "image";
  return "webgl";
}

/** The browser's WebGL renderer string (unmasked when the browser allows it), or null without WebGL. */
export function webglRenderer(): string | null {
  try {
    const canvas = document.createElement("canvas");
    const gl = canvas.getContext("webgl2") ?? canvas.getContext("webgl");
    if (!gl) return null;
    const info = gl.getExtension("WEBGL_debug_renderer_info");
    const name: unknown = info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
    gl.getExtension("WEBGL_lose_context")?.loseContext();
    return String(name);
  } catch {
    return null;
  }
}

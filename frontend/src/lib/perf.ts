// Timing marks the benchmarks read (bench/bench_ui.py): ``window.__driftmapPerf[name]`` is the
// ``performance.now()`` (milliseconds since the page's navigation started) when ``name`` last happened, e.g.
// "survey-coarse" and "survey-detail" when the survey plan's layers finished rendering.

declare global {
  interface Window {
    __driftmapPerf?: Record<string, number>;
  }
}

/** Record that ``name`` happened now (or at ``at`` ms); also counts how often as ``name#count``. */
export function mark(
  name: string,
  at: number = performance.now(),
  target: Window | undefined = globalThis.window,
): void {
  if (!target) return;
  const marks = (target.__driftmapPerf ??= {});
  marks[name] = at;
  marks[`${name}#count`] = (marks[`${name}#count`] ?? 0) + 1;
}

// A map build as the surveyor sees it: the presets to choose from, each with a line saying what it trades, and
// the build job's progress over all its stages (the job reports a fraction within each stage, which restarts at
// 0 % on every stage) with an estimate of the time left.
import { formatAge } from "./time";

export interface Preset {
  name: "paper" | "fast";
  label: string;
  /** One line: what the preset does and what it costs. */
  explanation: string;
}

export const PRESETS: readonly Preset[] = [
  {
    name: "paper",
    label: "paper (full)",
    explanation:
      "The paper's parameters: 2 cm odometry grid, the full loop-closure search, keyframes every 1 m. The most closures; the slowest.",
  },
  {
    name: "fast",
    label: "fast (preview)",
    explanation:
      "4 cm odometry grid, a shorter loop-closure search, keyframes every 2 m: several times quicker, but far fewer loop closures.",
  },
];

/** The build's stages in order with their share of the whole (rough shares of a build's time). */
export const BUILD_STAGES: readonly (readonly [string, number])[] = [
  ["loading drives", 0.02],
  ["odometry", 0.6],
  ["loop closure", 0.3],
  ["pose graph", 0.06],
  ["topological map", 0.02],
];

const ENDED = new Set(["succeeded", "failed", "cancelled"]);

/**
 * The fraction (0..1) of the whole build done when the job says ``fraction`` of ``stage``: the shares of the
 * stages before it plus that part of its own. A succeeded job is 1; an unknown stage counts as the start.
 */
export function overallProgress(status: string, stage: string, fraction: number): number {
  if (status === "succeeded") return 1;
  const at = BUILD_STAGES.findIndex(([name]) => name === stage);
  if (at < 0) return 0;
  const before = BUILD_STAGES.slice(0, at).reduce((sum, [, share]) => sum + share, 0);
  const share = BUILD_STAGES[at]![1];
  return Math.min(1, before + share * Math.min(1, Math.max(0, fraction)));
}

/** Below this much of the build or this many seconds of it, no estimate is made (it would be a guess). */
const MIN_DONE = 0.03;
const MIN_ELAPSED_S = 3;

/**
 * Seconds left of a build ``done`` (0..1) after ``elapsedS`` seconds of running, at the pace so far; null
 * before there is enough to go by.
 */
export function secondsLeft(done: number, elapsedS: number): number | null {
  if (done < MIN_DONE || elapsedS < MIN_ELAPSED_S || done >= 1) return null;
  return (elapsedS * (1 - done)) / done;
}

/** The line under the progress bar: status, overall percentage, stage and the time left. */
export function progressText(status: string, stage: string, done: number, left: number | null): string {
  if (status === "queued") return "queued: waiting for a worker";
  const percent = `${Math.round(done * 100)}%`;
  if (ENDED.has(status)) return `${status} ${status === "succeeded" ? "" : percent}`.trim();
  const eta = left === null ? "estimating the time left" : `about ${formatAge(Math.max(1, left))} left`;
  return `${percent} · ${stage || "starting"} · ${eta}`;
}

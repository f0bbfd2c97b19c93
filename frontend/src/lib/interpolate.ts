// Vehicle markers glide from where they are drawn to each new estimate instead of jumping.

export interface Pose {
  x: number;
  y: number;
  yaw: number | null;
}

/** The shortest signed turn from angle ``a`` to ``b`` (radians), in (-pi, pi]. */
export function angleDelta(a: number, b: number): number {
  let d = (b - a) % (2 * Math.PI);
  if (d > Math.PI) d -= 2 * Math.PI;
  if (d <= -Math.PI) d += 2 * Math.PI;
  return d;
}

/** Ease-out between two poses; ``u`` in [0, 1] is clamped; heading turns the short way round. */
export function lerpPose(from: Pose, to: Pose, u: number): Pose {
  const t = Math.min(1, Math.max(0, u));
  const e = 1 - (1 - t) * (1 - t);
  let yaw: number | null = to.yaw;
  if (from.yaw !== null && to.yaw !== null) yaw = from.yaw + angleDelta(from.yaw, to.yaw) * e;
  return { x: from.x + (to.x - from.x) * e, y: from.y + (to.y - from.y) * e, yaw };
}

/** A marker's glide: started at ``startMs`` from ``from`` towards ``to`` over ``durationMs``. */
export class Glide {
  private from: Pose;
  private to: Pose;
  private startMs: number;

  constructor(
    pose: Pose,
    nowMs: number,
    readonly durationMs = 600,
  ) {
    this.from = pose;
    this.to = pose;
    this.startMs = nowMs;
  }

  /** Where the marker is drawn at ``nowMs``. */
  at(nowMs: number): Pose {
    return this.durationMs <= 0 ? this.to : lerpPose(this.from, this.to, (nowMs - this.startMs) / this.durationMs);
  }

  /** Aim at a new estimate, starting from where the marker is drawn now (no jump mid-glide). */
  retarget(pose: Pose, nowMs: number): void {
    this.from = this.at(nowMs);
    this.to = pose;
    this.startMs = nowMs;
  }

  done(nowMs: number): boolean {
    return nowMs - this.startMs >= this.durationMs;
  }

  get target(): Pose {
    return this.to;
  }
}

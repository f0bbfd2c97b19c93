// The grounding panel's header: the map version shown and, for surveyors, "Build map" with a choice of preset
// (each explained in a line), which starts a map build job and shows its overall progress and the time left
// until it ends; a build of the site already queued or running (anyone's) is shown the same way when the panel
// opens, and a refusal (such a build started meanwhile) is said under the button, that build then shown.
// ``onBuilt`` runs when the new version is stored.
import { useCallback, useEffect, useState } from "react";
import { ApiError, apiGet, apiPost, type Schemas } from "../api/client";
import { PRESETS, overallProgress, progressText, secondsLeft, type Preset } from "../lib/buildProgress";
import { serverDate } from "../lib/time";
import { useNow } from "../lib/useNow";

type Job = Schemas["JobRead"];

const POLL_MS = 1000;
const ENDED = ["succeeded", "failed", "cancelled"];

interface Props {
  siteId: number;
  version: number | null;
  editable: boolean;
  onBuilt: () => Promise<void>;
  onError: (message: string) => void;
}

export function BuildMap({ siteId, version, editable, onBuilt, onError }: Props) {
  const [job, setJob] = useState<Job | null>(null);
  const [preset, setPreset] = useState<Preset["name"]>("paper");
  const [full, setFull] = useState(false);
  const [refused, setRefused] = useState<string | null>(null);
  const [looked, setLooked] = useState(false); // the panel has asked for a build under way
  const running = job !== null && !ENDED.includes(job.status);
  const now = useNow(POLL_MS);

  /** Show the site's build that is running or queued, if any. */
  const attach = useCallback(async () => {
    for (const status of ["running", "queued"] as const) {
      const page = await apiGet("/api/jobs", {}, { site_id: siteId, kind: "map.build", status, limit: 1 });
      if (page.items[0]) {
        setJob(page.items[0]);
        return;
      }
    }
  }, [siteId]);

  useEffect(() => {
    // attach sets state only after its requests resolve
    // eslint-disable-next-line react-hooks/set-state-in-effect
    void attach()
      .catch(() => undefined)
      .finally(() => setLooked(true));
  }, [attach]);

  const build = async () => {
    setRefused(null);
    try {
      setJob(await apiPost("/api/sites/{site_id}/maps", { site_id: siteId }, { preset, full }));
    } catch (e) {
      const text = e instanceof ApiError ? e.message : String(e);
      setRefused(text);
      onError(text);
      if (e instanceof ApiError && e.status === 409) await attach();
    }
  };

  useEffect(() => {
    if (!job || ENDED.includes(job.status)) return;
    const timer = setTimeout(async () => {
      const next = await apiGet("/api/jobs/{job_id}", { job_id: job.id });
      if (next.status === "succeeded") await onBuilt();
      setJob(next);
    }, POLL_MS);
    return () => clearTimeout(timer);
  }, [job, onBuilt]);

  const chosen = PRESETS.find((p) => p.name === preset) ?? PRESETS[0]!;
  const done = job ? overallProgress(job.status, job.stage, job.progress) : 0;
  const elapsedS = job?.started_at ? (now - serverDate(job.started_at).getTime()) / 1000 : 0;
  const left = job && job.status === "running" ? secondsLeft(done, elapsedS) : null;
  const jobPreset = typeof job?.args.preset === "string" ? job.args.preset : "";
  return (
    <>
      <div className="row">
        <h2 style={{ margin: 0 }}>Grounding</h2>
        <span className="spacer" />
        <span className="muted" data-testid="map-version">
          {version === null ? "no map yet" : `map v${version}`}
        </span>
      </div>
      {editable && (
        <>
          <div className="row">
            <label>
              preset{" "}
              <select
                data-testid="build-preset"
                value={preset}
                disabled={running}
                onChange={(e) => setPreset(e.target.value as Preset["name"])}
              >
                {PRESETS.map((p) => (
                  <option key={p.name} value={p.name}>
                    {p.label}
                  </option>
                ))}
              </select>
            </label>
            <label title="Prepare every drive's odometry again and search loop closures afresh instead of reusing what earlier builds kept for drives that did not change">
              <input
                type="checkbox"
                data-testid="build-full"
                checked={full}
                disabled={running}
                onChange={(e) => setFull(e.target.checked)}
              />{" "}
              full rebuild
            </label>
            <span className="spacer" />
            <button
              className="primary"
              data-testid="build-map"
              data-looked={looked ? "yes" : "no"}
              onClick={() => void build()}
              disabled={running}
            >
              Build map
            </button>
          </div>
          <div className="muted small" data-testid="build-preset-explanation">
            {chosen.explanation}
          </div>
        </>
      )}
      {refused && (
        <div className="error" data-testid="build-refused">
          {refused}
        </div>
      )}
      {job && (
        <div data-testid="build-job" data-status={job.status} data-progress={done.toFixed(3)} data-preset={jobPreset}>
          <div className="progress">
            <div style={{ width: `${Math.round(done * 100)}%` }} />
          </div>
          <span className="muted">
            job {job.id} ({jobPreset}): {progressText(job.status, job.stage, done, left)}
          </span>
          {job.error && <div className="error">{job.error}</div>}
        </div>
      )}
    </>
  );
}

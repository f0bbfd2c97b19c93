// The grounding panel's header: the map version shown and, for surveyors, "Build map", which starts a map
// build job and shows its progress until it ends; ``onBuilt`` runs when the new version is stored.
import { useEffect, useState } from "react";
import { ApiError, apiGet, apiPost, type Schemas } from "../api/client";

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
  const running = job !== null && !ENDED.includes(job.status);

  const build = async () => {
    try {
      setJob(await apiPost("/api/sites/{site_id}/maps", { site_id: siteId }, { preset: "fast" }));
    } catch (e) {
      onError(e instanceof ApiError ? e.message : String(e));
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

  return (
    <>
      <div className="row">
        <h2 style={{ margin: 0 }}>Grounding</h2>
        <span className="spacer" />
        <span className="muted" data-testid="map-version">
          {version === null ? "no map yet" : `map v${version}`}
        </span>
        {editable && (
          <button className="primary" data-testid="build-map" onClick={() => void build()} disabled={running}>
            Build map
          </button>
        )}
      </div>
      {job && (
        <div data-testid="build-job" data-status={job.status}>
          <div className="progress">
            <div style={{ width: `${Math.round(job.progress * 100)}%` }} />
          </div>
          <span className="muted">
            job {job.id}: {job.status} {job.stage} {Math.round(job.progress * 100)}%
          </span>
          {job.error && <div className="error">{job.error}</div>}
        </div>
      )}
    </>
  );
}

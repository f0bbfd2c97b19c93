// Admin: upload a site's DXF plan, a zipped drive folder or a drive video (with its calibration file or a
// stored camera profile), each with the upload's progress; a drive is then imported by a job, named here.
import { useEffect, useState, type ReactNode } from "react";
import { ApiError, apiGet, apiUploadForm, type Schemas } from "../api/client";
import { fileForm, uploadProgressText, videoForm } from "../lib/upload";

type Profile = Schemas["CameraProfileRead"];
type State =
  { state: "idle" } | { state: "sending"; loaded: number; total: number } | { state: "done" | "refused"; text: string };

/** One upload's progress bar and outcome. */
function useUpload(): [State, (send: (progress: (l: number, t: number) => void) => Promise<string>) => void] {
  const [state, setState] = useState<State>({ state: "idle" });
  const start = (send: (progress: (l: number, t: number) => void) => Promise<string>) => {
    setState({ state: "sending", loaded: 0, total: 0 });
    send((loaded, total) => setState({ state: "sending", loaded, total })).then(
      (text) => setState({ state: "done", text }),
      (e: unknown) => setState({ state: "refused", text: e instanceof ApiError ? e.message : String(e) }),
    );
  };
  return [state, start];
}

function Progress({ id, state }: { id: string; state: State }) {
  if (state.state === "idle") return null;
  const fraction =
    state.state === "sending" ? (state.total > 0 ? state.loaded / state.total : 0) : state.state === "done" ? 1 : 0;
  return (
    <div data-testid={`upload-${id}`} data-state={state.state}>
      <div className="progress">
        <div style={{ width: `${Math.round(fraction * 100)}%` }} />
      </div>
      <span className={state.state === "refused" ? "error" : "muted"}>
        {state.state === "sending" ? uploadProgressText(state.loaded, state.total) : state.text}
      </span>
    </div>
  );
}

/** A file picker that hands the chosen file (or null when cleared) to ``onFile``. */
function FileInput({ testId, accept, onFile }: { testId: string; accept: string; onFile: (f: File | null) => void }) {
  return (
    <input type="file" accept={accept} data-testid={testId} onChange={(e) => onFile(e.target.files?.[0] ?? null)} />
  );
}

function Field({ label, children }: { label: string; children: ReactNode }) {
  return (
    <label className="row" style={{ margin: "2px 0" }}>
      <span className="muted" style={{ minWidth: 90 }}>
        {label}
      </span>
      {children}
    </label>
  );
}

export function Uploads({ sites }: { sites: Schemas["SiteRead"][] }) {
  const [siteId, setSiteId] = useState<number | null>(null);
  const site = siteId ?? sites[0]?.id ?? null;
  const [profiles, setProfiles] = useState<Profile[]>([]);
  const [plan, setPlan] = useState<File | null>(null);
  const [zip, setZip] = useState<File | null>(null);
  const [video, setVideo] = useState<File | null>(null);
  const [calibration, setCalibration] = useState<File | null>(null);
  const [profileId, setProfileId] = useState<number | null>(null);
  const [name, setName] = useState("");
  const [kind, setKind] = useState<"mapping" | "localisation">("mapping");
  const [planState, sendPlan] = useUpload();
  const [zipState, sendZip] = useUpload();
  const [videoState, sendVideo] = useUpload();

  useEffect(() => {
    void apiGet("/api/camera-profiles", {}, { limit: 500 }).then(
      (page) => setProfiles(page.items),
      () => setProfiles([]),
    );
  }, []);

  const refuse = (error: string) => () => Promise.reject(new Error(error));
  const uploadPlan = () => {
    const made = fileForm(plan, "a DXF plan");
    sendPlan(
      "error" in made || site === null
        ? refuse("error" in made ? made.error : "no site")
        : async (progress) => {
            const stored = await apiUploadForm("/api/sites/{site_id}/survey", { site_id: site }, made.form, progress);
            return `plan ${stored.filename} stored: it is the site's plan now`;
          },
    );
  };
  const uploadZip = () => {
    const made = fileForm(zip, "a zipped drive folder");
    sendZip(
      "error" in made || site === null
        ? refuse("error" in made ? made.error : "no site")
        : async (progress) => {
            const job = await apiUploadForm("/api/sites/{site_id}/drives/zip", { site_id: site }, made.form, progress);
            return `uploaded; imported by job ${job.id} (${job.status})`;
          },
    );
  };
  const uploadVideo = () => {
    const made = videoForm({ video, calibration, profileId, name, kind });
    sendVideo(
      "error" in made || site === null
        ? refuse("error" in made ? made.error : "no site")
        : async (progress) => {
            const job = await apiUploadForm(
              "/api/sites/{site_id}/drives/video",
              { site_id: site },
              made.form,
              progress,
            );
            return `uploaded; imported by job ${job.id} (${job.status})`;
          },
    );
  };
  const busy = [planState, zipState, videoState].some((s) => s.state === "sending");

  return (
    <section className="card" data-testid="admin-uploads">
      <h2>Uploads</h2>
      <Field label="Site">
        <select data-testid="upload-site" value={site ?? ""} onChange={(e) => setSiteId(Number(e.target.value))}>
          {sites.map((s) => (
            <option key={s.id} value={s.id}>
              {s.name}
            </option>
          ))}
        </select>
      </Field>
      <h3>Survey plan (DXF)</h3>
      <div className="row">
        <FileInput testId="upload-plan-file" accept=".dxf" onFile={setPlan} />
        <button data-testid="upload-plan-send" disabled={busy} onClick={uploadPlan}>
          Upload plan
        </button>
      </div>
      <Progress id="plan" state={planState} />
      <h3>Drive (zipped folder)</h3>
      <div className="row">
        <FileInput testId="upload-zip-file" accept=".zip" onFile={setZip} />
        <button data-testid="upload-zip-send" disabled={busy} onClick={uploadZip}>
          Upload drive
        </button>
      </div>
      <Progress id="zip" state={zipState} />
      <h3>Drive (video)</h3>
      <Field label="Video">
        <FileInput testId="upload-video-file" accept=".mp4,.avi,.mov,.mkv,video/*" onFile={setVideo} />
      </Field>
      <Field label="Calibration">
        <FileInput testId="upload-video-calibration" accept=".json" onFile={setCalibration} />
      </Field>
      <Field label="or profile">
        <select
          data-testid="upload-video-profile"
          value={profileId ?? ""}
          onChange={(e) => setProfileId(e.target.value === "" ? null : Number(e.target.value))}
        >
          <option value="">none</option>
          {profiles.map((p) => (
            <option key={p.id} value={p.id}>
              {p.name}
            </option>
          ))}
        </select>
      </Field>
      <Field label="Name">
        <input placeholder="the video's file name" value={name} onChange={(e) => setName(e.target.value)} />
      </Field>
      <div className="row">
        <select value={kind} onChange={(e) => setKind(e.target.value as "mapping" | "localisation")}>
          <option value="mapping">mapping drive</option>
          <option value="localisation">localisation drive</option>
        </select>
        <span className="spacer" />
        <button data-testid="upload-video-send" disabled={busy} onClick={uploadVideo}>
          Upload video
        </button>
      </div>
      <Progress id="video" state={videoState} />
    </section>
  );
}

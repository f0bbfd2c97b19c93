// Check against a drive: a site's stored drive, a straight drive over a measured distance (the floor scale) or a
// turn (the mounting: forward_sign, the turn's direction, the lever y_c), the camera on the page when it is
// complete (else the drive's own), the figures found, and the corrected camera taken into the page. The server
// dead-reckons the drive while the request waits; its refusal is shown and the form kept.
import { useEffect, useState } from "react";
import { postCameraCheck } from "../../api/cameras";
import { apiGet, type Schemas } from "../../api/client";
import {
  checkBody,
  checkLines,
  correctionText,
  isCheckable,
  type CameraBlock,
  type CheckForm,
  type CheckKind,
  type CheckRead,
  type CheckRequest,
  type Tone,
} from "../../lib/cameraCheck";
import { useErrors } from "../useErrors";

type Drive = Schemas["DriveRead"];

interface Props {
  /** The camera on the page when it is complete (fitted, or a drive's corrected camera taken), else null. */
  block: CameraBlock | null;
  /** The page's camera is a drive's corrected camera taken by ``onUse`` (not a fit of the page's points). */
  taken: boolean;
  /** Put the corrected block's scale, y_c and forward_sign into the camera on the page. */
  onUse: (corrected: CameraBlock) => void;
}

/** A check's answer with what it was asked: the body, which camera, and the page's state it was run against. */
interface Outcome {
  read: CheckRead;
  body: CheckRequest;
  checked: string;
  key: string;
}

const TONE_CLASS: Record<Exclude<Tone, null>, string> = { ok: "ok", warn: "res-fair", error: "error" };

/** A camera block in a few words: its frame size, lever and which way it looks. */
function summary(camera: CameraBlock): string {
  const looks = camera.forward_sign === -1 ? "−1" : "+1";
  return `${camera.width}x${camera.height}, y_c ${camera.y_c.toFixed(3)} m, forward_sign ${looks}`;
}

export function DriveCheckPanel({ block, taken, onUse }: Props) {
  const [sites, setSites] = useState<Schemas["SiteRead"][]>([]);
  const [siteId, setSiteId] = useState<number | null>(null);
  const [drives, setDrives] = useState<Drive[]>([]);
  const [driveId, setDriveId] = useState<number | null>(null);
  const [form, setForm] = useState<CheckForm>({ kind: "distance", amount: "", reverse: false });
  const [busy, setBusy] = useState(false);
  const [outcome, setOutcome] = useState<Outcome | null>(null);
  const [used, setUsed] = useState<string | null>(null);
  const [error, run] = useErrors();

  useEffect(
    () =>
      void run(async () => {
        const page = await apiGet("/api/sites", {}, { limit: 500 });
        setSites(page.items);
        setSiteId((id) => id ?? page.items[0]?.id ?? null);
      }),
    [run],
  );
  useEffect(() => {
    if (siteId === null) return;
    void run(async () => {
      const page = await apiGet("/api/sites/{site_id}/drives", { site_id: siteId }, { limit: 500 });
      setDrives(page.items);
      setDriveId(page.items[0]?.id ?? null);
    });
  }, [run, siteId]);

  const drive = drives.find((d) => d.id === driveId) ?? null;
  const own = drive && isCheckable(drive.camera) ? drive.camera : null;
  const which = block
    ? `the camera on this page${taken ? " (a drive's corrected camera)" : ""}`
    : drive
      ? `drive ${drive.name}'s own camera`
      : null;
  const shown = block ?? own;
  const { body, blocked } = checkBody(form, block);
  const reason = !drive ? "Choose a drive" : blocked;
  const key = JSON.stringify([driveId, block]);
  const stale = outcome !== null && outcome.key !== key;
  const corrected = outcome && isCheckable(outcome.read.camera) ? outcome.read.camera : null;
  const lines = outcome ? checkLines(outcome.read, outcome.body) : [];

  const check = () =>
    void run(async () => {
      if (!drive || !body || !which) return;
      setBusy(true);
      setOutcome(null);
      setUsed(null);
      try {
        const read = await postCameraCheck(drive.id, body);
        setOutcome({ read, body, checked: block ? `${which} against drive ${drive.name}` : which, key });
      } finally {
        setBusy(false);
      }
    });
  const use = () => {
    if (!corrected || !outcome) return;
    onUse(corrected);
    setUsed(`The camera on this page now has ${correctionText(corrected, outcome.body.distance_m != null)}.`);
  };

  return (
    <section data-testid="camera-check">
      <h3>Check against a drive</h3>
      <div className="row">
        <select
          value={siteId ?? ""}
          onChange={(e) => setSiteId(e.target.value ? Number(e.target.value) : null)}
          data-testid="camera-check-site"
        >
          {sites.length === 0 && <option value="">no sites</option>}
          {sites.map((s) => (
            <option key={s.id} value={s.id}>
              {s.name}
            </option>
          ))}
        </select>
        <select
          value={driveId ?? ""}
          onChange={(e) => setDriveId(e.target.value ? Number(e.target.value) : null)}
          data-testid="camera-check-drive"
        >
          {drives.length === 0 && <option value="">no drives</option>}
          {drives.map((d) => (
            <option key={d.id} value={d.id}>
              {d.name} ({d.frame_count} frames)
            </option>
          ))}
        </select>
      </div>
      <div className="row">
        <select
          value={form.kind}
          onChange={(e) => setForm({ ...form, kind: e.target.value as CheckKind })}
          data-testid="camera-check-kind"
        >
          <option value="distance">straight drive, distance m</option>
          <option value="turn">turn, degrees (+ left)</option>
        </select>
        <input
          className="small"
          type="number"
          step="any"
          value={form.amount}
          onChange={(e) => setForm({ ...form, amount: e.target.value })}
          title={form.kind === "distance" ? "Metres driven, measured on the floor" : "Degrees turned, + left"}
          data-testid="camera-check-amount"
        />
        <label title="The drive was driven in reverse">
          <input
            type="checkbox"
            checked={form.reverse}
            onChange={(e) => setForm({ ...form, reverse: e.target.checked })}
            data-testid="camera-check-reverse"
          />{" "}
          driven in reverse
        </label>
      </div>
      {which && (
        <p className="muted" data-testid="camera-check-which">
          Checks {which}
          {shown ? ` (${summary(shown)})` : ""}
          {block ? "." : "; the camera on this page is not complete (fit the ground first)."}
        </p>
      )}
      <div className="row">
        <button
          className="primary"
          disabled={busy || reason !== null}
          title={reason ?? "Dead-reckon the drive with the camera (up to about 30 s)"}
          onClick={check}
          data-testid="camera-check-run"
        >
          {busy ? "Checking…" : "Run"}
        </button>
        {reason && <span className="muted">{reason}</span>}
        {busy && <span className="muted">the server dead-reckons the drive (up to about 30 s)</span>}
      </div>
      {error && (
        <div className="alert" role="alert" data-testid="camera-check-error">
          {error}
        </div>
      )}
      {outcome && (
        <>
          <p className="muted" data-testid="camera-check-checked">
            Checked {outcome.checked}.
          </p>
          {lines
            .filter((l) => l.tone === "error")
            .map((l) => (
              <div key={l.key} className="alert" role="alert" data-testid={`camera-check-${l.key}`}>
                {l.text}
              </div>
            ))}
          <table className="camcheck" data-testid="camera-check-result">
            <tbody>
              {lines
                .filter((l) => l.tone !== "error")
                .map((l) => (
                  <tr key={l.key}>
                    <td>{l.label}</td>
                    <td className={l.tone ? TONE_CLASS[l.tone] : ""} data-testid={`camera-check-${l.key}`}>
                      {l.text}
                    </td>
                  </tr>
                ))}
            </tbody>
          </table>
          <div className="row">
            <button
              disabled={!corrected || stale}
              title={
                !corrected
                  ? "The check gives no corrected camera"
                  : stale
                    ? "The camera or drive changed since this check: run it again"
                    : "Put the corrected scale, y_c and forward_sign into the camera on this page"
              }
              onClick={use}
              data-testid="camera-check-use"
            >
              Use the corrected camera
            </button>
            {stale && !used && <span className="muted">changed since this check</span>}
          </div>
          {used && (
            <div className="ok" data-testid="camera-check-used">
              {used}
            </div>
          )}
        </>
      )}
    </section>
  );
}

// The admin page's uploads (the site's DXF plan, a zipped drive folder, a drive video): what each sends and
// how far along it is.

/** "3.2 of 10.0 MB (32%)": an upload's progress in megabytes and percent. */
export function uploadProgressText(loaded: number, total: number): string {
  const mb = (n: number) => (n / 1e6).toFixed(1);
  const percent = total > 0 ? Math.round((100 * loaded) / total) : 0;
  return `${mb(loaded)} of ${mb(total)} MB (${percent}%)`;
}

export interface VideoUpload {
  video: File | null;
  /** The calibration JSON (the ``camera`` block), or null when a stored camera profile is named instead. */
  calibration: File | null;
  profileId: number | null;
  /** The drive's name; blank: the video's file stem. */
  name: string;
  kind: "mapping" | "localisation";
}

/**
 * The multipart body of POST /api/sites/{id}/drives/video, or the reason it cannot be sent: a video, and
 * either a calibration file or a camera profile (not both, not neither).
 */
export function videoForm(u: VideoUpload): { form: FormData } | { error: string } {
  if (!u.video) return { error: "choose a video file" };
  if ((u.calibration === null) === (u.profileId === null)) {
    return { error: "give either a calibration file or a camera profile" };
  }
  const form = new FormData();
  form.append("video", u.video);
  if (u.calibration) form.append("calibration", u.calibration);
  if (u.profileId !== null) form.append("profile", String(u.profileId));
  if (u.name.trim()) form.append("name", u.name.trim());
  form.append("kind", u.kind);
  return { form };
}

/** The multipart body of a one-file upload (a plan or a drive zip: field ``file``), or why not. */
export function fileForm(file: File | null, what: string): { form: FormData } | { error: string } {
  if (!file) return { error: `choose ${what}` };
  const form = new FormData();
  form.append("file", file);
  return { form };
}

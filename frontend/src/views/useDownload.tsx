// One download button's state: fetch a route with the login token and save its answer as a file
// (apiDownload), busy while it runs, the server's reason when it refuses, the saved file's name when done.
import { useState } from "react";
import { ApiError, apiDownload } from "../api/client";

export interface Download {
  busy: boolean;
  /** The last refusal's text (the server's reason), null after a success or a new attempt. */
  error: string | null;
  /** The file name the last successful download was saved under. */
  saved: string | null;
  /** Download ``url`` (saved under the server's name for it, else ``filename``). */
  run: (url: string, filename: string) => Promise<void>;
  /** Show ``text`` as the error without asking the server (e.g. an unreadable input). */
  fail: (text: string) => void;
}

export function useDownload(): Download {
  const [busy, setBusy] = useState(false);
  const [error, setError] = useState<string | null>(null);
  const [saved, setSaved] = useState<string | null>(null);
  const run = async (url: string, filename: string) => {
    setBusy(true);
    setError(null);
    setSaved(null);
    try {
      setSaved(await apiDownload(url, filename));
    } catch (e) {
      setError(
        e instanceof ApiError
          ? `The server refused the export: ${e.message} (HTTP ${e.status})`
          : `The export failed: ${String(e)}`,
      );
    } finally {
      setBusy(false);
    }
  };
  const fail = (text: string) => {
    setSaved(null);
    setError(text);
  };
  return { busy, error, saved, run, fail };
}

/** The download's outcome under its controls: the refusal (an alert) or the saved file's name. */
export function DownloadStatus({ download, testId }: { download: Download; testId: string }) {
  if (download.error) {
    return (
      <div className="error" role="alert" data-testid={`${testId}-error`}>
        {download.error}
      </div>
    );
  }
  if (download.saved) {
    return (
      <div className="muted" data-testid={`${testId}-saved`}>
        Saved {download.saved}
      </div>
    );
  }
  return null;
}

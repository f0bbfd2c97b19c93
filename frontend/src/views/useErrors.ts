// A view's last error: ``run`` clears it, awaits the action and keeps the API's message when it fails.
import { useCallback, useState } from "react";
import { ApiError } from "../api/client";

/** The text to show for a failed action: the API's problem text (see ``detailText``), else the error's own. */
export function errorText(e: unknown): string {
  if (e instanceof ApiError) return e.message || e.problem?.title || `HTTP ${e.status}`;
  return e instanceof Error ? e.message : String(e);
}

export function useErrors(): [string | null, (f: () => Promise<void>) => Promise<void>] {
  const [error, setError] = useState<string | null>(null);
  const run = useCallback(async (f: () => Promise<void>) => {
    setError(null);
    try {
      await f();
    } catch (e) {
      setError(errorText(e));
    }
  }, []);
  return [error, run];
}

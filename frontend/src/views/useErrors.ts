// A view's last error: ``run`` clears it, awaits the action and keeps the API's message when it fails.
import { useCallback, useState } from "react";
import { ApiError } from "../api/client";

export function useErrors(): [string | null, (f: () => Promise<void>) => Promise<void>] {
  const [error, setError] = useState<string | null>(null);
  const run = useCallback(async (f: () => Promise<void>) => {
    setError(null);
    try {
      await f();
    } catch (e) {
      setError(e instanceof ApiError ? e.message : String(e));
    }
  }, []);
  return [error, run];
}

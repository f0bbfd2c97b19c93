// The selected vehicle's last localised frame, fetched with the bearer token when its estimate changes (at
// most once a second); the previous picture stays until the next has loaded, so it never flickers.
import { useEffect, useRef, useState } from "react";
import { getToken } from "../api/client";

const MIN_INTERVAL_MS = 1000;

export function LatestFrame({ vehicleId, seq }: { vehicleId: number; seq: number | undefined }) {
  const [shown, setShown] = useState<{ url: string; t: string } | null>(null);
  const [missing, setMissing] = useState(false);
  const lastFetch = useRef(0);
  const urlRef = useRef<string | null>(null);

  useEffect(() => {
    if (seq === undefined) return; // no position yet, so no frame to ask for
    let cancelled = false;
    const wait = Math.max(0, lastFetch.current + MIN_INTERVAL_MS - performance.now());
    const timer = window.setTimeout(async () => {
      lastFetch.current = performance.now();
      const token = getToken();
      try {
        const r = await fetch(`/api/vehicles/${vehicleId}/frames/latest`, {
          headers: token ? { Authorization: `Bearer ${token}` } : {},
          cache: "no-store",
        });
        if (cancelled) return;
        if (!r.ok) {
          setMissing(true);
          return;
        }
        const t = r.headers.get("X-Frame-T") ?? "";
        const url = URL.createObjectURL(await r.blob());
        if (cancelled) {
          URL.revokeObjectURL(url);
          return;
        }
        if (urlRef.current) URL.revokeObjectURL(urlRef.current);
        urlRef.current = url;
        setMissing(false);
        setShown({ url, t });
      } catch {
        if (!cancelled) setMissing(true);
      }
    }, wait);
    return () => {
      cancelled = true;
      window.clearTimeout(timer);
    };
  }, [vehicleId, seq]);

  useEffect(
    () => () => {
      if (urlRef.current) URL.revokeObjectURL(urlRef.current);
    },
    [],
  );

  if (shown === null) {
    return missing || seq === undefined ? (
      <p className="muted">No frame from this vehicle on this server yet.</p>
    ) : null;
  }
  return (
    <img
      src={shown.url}
      alt="latest frame"
      data-testid="latest-frame"
      data-t={shown.t}
      style={{ width: "100%", display: "block", borderRadius: 4, margin: "6px 0" }}
    />
  );
}

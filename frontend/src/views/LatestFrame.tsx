// The selected vehicle's last localised frame, fetched with the bearer token when its estimate changes (at
// most once a second) and labelled with the vehicle's name and the frame's time; a click opens it full size.
// Exactly one picture, and only ever the selected vehicle's: a picture fetched for another vehicle is never
// shown, and while the next picture of the same vehicle loads the previous one stays (no flicker).
import { useEffect, useRef, useState } from "react";
import { getToken } from "../api/client";
import { formatFrameTime } from "../lib/time";
import { Modal } from "./Dialog";

const MIN_INTERVAL_MS = 1000;

interface Shown {
  vehicleId: number;
  url: string;
  t: number;
}

export function LatestFrame({ vehicleId, name, seq }: { vehicleId: number; name: string; seq: number | undefined }) {
  const [shown, setShown] = useState<Shown | null>(null);
  const [missing, setMissing] = useState(false);
  const [full, setFull] = useState(false);
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
        const t = Number(r.headers.get("X-Frame-T") ?? "NaN");
        const url = URL.createObjectURL(await r.blob());
        if (cancelled) {
          URL.revokeObjectURL(url);
          return;
        }
        if (urlRef.current) URL.revokeObjectURL(urlRef.current);
        urlRef.current = url;
        setMissing(false);
        setShown({ vehicleId, url, t });
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

  const mine = shown !== null && shown.vehicleId === vehicleId ? shown : null;
  if (mine === null) {
    return missing || seq === undefined ? (
      <p className="muted" data-testid="latest-frame-missing">
        No frame from this vehicle on this server yet.
      </p>
    ) : null;
  }
  const when = Number.isFinite(mine.t) ? formatFrameTime(mine.t) : "—";
  const caption = `${name} · ${when}`;
  return (
    <figure className="latest-frame" data-testid="latest-frame-figure">
      <button className="frame-open" onClick={() => setFull(true)} title="Open full size">
        <img
          src={mine.url}
          alt={`latest frame of ${name}`}
          data-testid="latest-frame"
          data-vehicle={name}
          data-t={Number.isFinite(mine.t) ? String(mine.t) : ""}
        />
      </button>
      <figcaption className="muted" data-testid="latest-frame-caption">
        {caption}
      </figcaption>
      {full && (
        <Modal title={`Camera: ${caption}`} onClose={() => setFull(false)} testId="frame-full" wide>
          <img className="fullframe" src={mine.url} alt={`latest frame of ${name}, full size`} />
          <div className="row">
            <span className="spacer" />
            <button onClick={() => setFull(false)} data-testid="frame-full-close">
              Close
            </button>
          </div>
        </Modal>
      )}
    </figure>
  );
}

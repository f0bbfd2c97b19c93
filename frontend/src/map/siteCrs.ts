// A site's coordinates (``crs`` of GET /api/sites/{id}) for the readouts: fetched once per site and view, and
// updated everywhere at once when the settings form saves new ones (publishSiteCrs).
import { useEffect, useMemo, useState } from "react";
import { apiGet } from "../api/client";
import { siteCoordinatesOf, type SiteCoordinates, type SiteCrs } from "../lib/siteCoordinates";

type Listener = (siteId: number, crs: SiteCrs | null) => void;
const listeners = new Set<Listener>();

/** Tell every readout that a site's coordinates are now ``crs`` (the PUT's answer). */
export function publishSiteCrs(siteId: number, crs: SiteCrs | null): void {
  for (const listener of listeners) listener(siteId, crs);
}

/**
 * The site's coordinates as stored: undefined while loading, null when it has none (or they could not be read:
 * the readouts then show plane metres only).
 */
export function useSiteCrs(siteId: number): SiteCrs | null | undefined {
  const [state, setState] = useState<{ siteId: number; crs: SiteCrs | null } | null>(null);
  useEffect(() => {
    let cancelled = false;
    let published = false; // a save after the request went out wins over its answer
    const listener: Listener = (id, crs) => {
      if (id !== siteId) return;
      published = true;
      setState({ siteId, crs });
    };
    listeners.add(listener);
    apiGet("/api/sites/{site_id}", { site_id: siteId })
      .then((site) => !cancelled && !published && setState({ siteId, crs: site.crs ?? null }))
      .catch(() => !cancelled && !published && setState({ siteId, crs: null }));
    return () => {
      cancelled = true;
      listeners.delete(listener);
    };
  }, [siteId]);
  return state?.siteId === siteId ? state.crs : undefined;
}

/** The conversions of the site's coordinates (null without any), for the readouts. */
export function useSiteCoordinates(siteId: number): SiteCoordinates | null {
  const crs = useSiteCrs(siteId);
  return useMemo(() => siteCoordinatesOf(crs), [crs]);
}

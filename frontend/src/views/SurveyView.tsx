// The survey map, and beside it the site's coordinates (SiteCrsForm: surveyors and admins edit them).
import { useEffect, useState } from "react";
import { apiGet } from "../api/client";
import { MineMap } from "../map/MineMap";
import { canEdit } from "../session";
import { SiteCrsForm } from "./SiteCrsForm";

/** Whether the logged-in user may edit (surveyor or admin); null until known. */
function useCanEdit(): boolean | null {
  const [editable, setEditable] = useState<boolean | null>(null);
  useEffect(() => {
    let cancelled = false;
    apiGet("/api/auth/me")
      .then((me) => !cancelled && setEditable(canEdit(me)))
      .catch(() => !cancelled && setEditable(false));
    return () => {
      cancelled = true;
    };
  }, []);
  return editable;
}

export function SurveyView({ siteId }: { siteId: number }) {
  const editable = useCanEdit();
  return (
    <>
      <MineMap key={siteId} siteId={siteId} />
      <aside className="side" data-testid="site-coordinates">
        <h2 style={{ marginTop: 0 }}>Site coordinates</h2>
        <p className="muted" style={{ fontSize: 12 }}>
          Where the plan sits on the mine grid and, with an EPSG code, on the Earth: the readout under the pointer shows
          grid and longitude/latitude then, and GeoJSON and KML exports are in WGS84.
        </p>
        {editable !== null && <SiteCrsForm key={siteId} siteId={siteId} editable={editable} />}
      </aside>
    </>
  );
}

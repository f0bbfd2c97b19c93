// The site's coordinates (docs/formats.md, "Site coordinates"): how its plan sits on the mine grid (false
// origin, rotation, scale) and, with an EPSG code, on the Earth. Surveyors and admins edit them (Save: PUT
// /api/sites/{id}/crs; Clear: the defaults' body), a refusal shows next to the field it names; viewers read them.
import { useState, type FormEvent } from "react";
import { ApiError, apiPut, type Schemas } from "../api/client";
import { publishSiteCrs, useSiteCrs } from "../map/siteCrs";
import {
  CLEAR_CRS,
  CRS_FIELDS,
  crsBodyOf,
  crsFormOf,
  refusedField,
  type CrsBody,
  type CrsField,
  type CrsForm,
  type SiteCrs,
} from "../lib/siteCoordinates";

const LABELS: Record<CrsField, { label: string; unit: string; hint: string }> = {
  epsg: {
    label: "EPSG code",
    unit: "",
    hint: "The projected system (metres) of the mine grid, e.g. 28355; empty: none",
  },
  false_easting_m: { label: "False easting", unit: "m", hint: "Grid easting of the plan's origin" },
  false_northing_m: { label: "False northing", unit: "m", hint: "Grid northing of the plan's origin" },
  rotation_deg: { label: "Rotation", unit: "°", hint: "Counter-clockwise from the plan's +x to grid east" },
  scale: { label: "Scale", unit: "", hint: "Grid metres per plan metre (0.5-2)" },
};

/** PUT the site's coordinates; the answer's ``crs`` (null when cleared). Refusals throw an ApiError. */
async function putCrs(siteId: number, body: CrsBody): Promise<SiteCrs | null> {
  const site = await apiPut("/api/sites/{site_id}/crs", { site_id: siteId }, body satisfies Schemas["SiteCrsBody"]);
  return site.crs ?? null;
}

function ReadOnly({ crs }: { crs: SiteCrs | null }) {
  if (!crs) return <p className="muted">None: positions are in plan metres only.</p>;
  const form = crsFormOf(crs);
  return (
    <table data-testid="crs-readonly">
      <tbody>
        {CRS_FIELDS.map((f) => (
          <tr key={f}>
            <th title={LABELS[f].hint}>{LABELS[f].label}</th>
            <td className="num" data-testid={`crs-value-${f}`}>
              {form[f] === "" ? "none" : `${form[f]} ${LABELS[f].unit}`.trim()}
            </td>
          </tr>
        ))}
      </tbody>
    </table>
  );
}

export function SiteCrsForm({ siteId, editable }: { siteId: number; editable: boolean }) {
  const stored = useSiteCrs(siteId);
  const [edits, setEdits] = useState<CrsForm | null>(null);
  const [errors, setErrors] = useState<Partial<Record<CrsField, string>>>({});
  const [general, setGeneral] = useState<string | null>(null);
  const [status, setStatus] = useState<string | null>(null);
  const [busy, setBusy] = useState(false);

  if (stored === undefined) return <p className="muted">Loading the site's coordinates…</p>;
  const form = edits ?? crsFormOf(stored);

  const send = async (body: CrsBody, done: string) => {
    setBusy(true);
    setErrors({});
    setGeneral(null);
    setStatus(null);
    try {
      const crs = await putCrs(siteId, body);
      publishSiteCrs(siteId, crs);
      setEdits(null);
      setStatus(done);
    } catch (e) {
      const message = e instanceof Error ? e.message : String(e);
      const field = e instanceof ApiError && e.status === 422 ? refusedField(message) : null;
      if (field) setErrors({ [field]: message });
      else setGeneral(e instanceof ApiError ? `${message} (HTTP ${e.status})` : message);
    } finally {
      setBusy(false);
    }
  };

  const save = (e: FormEvent) => {
    e.preventDefault();
    const built = crsBodyOf(form);
    if ("errors" in built) {
      setErrors(built.errors);
      setStatus(null);
      return;
    }
    void send(built.body, "Saved.");
  };

  if (!editable) return <ReadOnly crs={stored} />;
  return (
    <form onSubmit={save} data-testid="crs-form" noValidate>
      <table>
        <tbody>
          {CRS_FIELDS.map((f) => (
            <tr key={f}>
              <th>
                <label htmlFor={`crs-${f}`} title={LABELS[f].hint}>
                  {LABELS[f].label}
                  {LABELS[f].unit && <span className="muted"> ({LABELS[f].unit})</span>}
                </label>
              </th>
              <td>
                <input
                  id={`crs-${f}`}
                  data-testid={`crs-${f}`}
                  inputMode={f === "epsg" ? "numeric" : "decimal"}
                  placeholder={f === "epsg" ? "none" : undefined}
                  title={LABELS[f].hint}
                  value={form[f]}
                  aria-invalid={errors[f] ? true : undefined}
                  onChange={(e) => {
                    setEdits({ ...form, [f]: e.target.value });
                    setStatus(null);
                  }}
                  style={{ width: "100%", boxSizing: "border-box" }}
                />
                {errors[f] && (
                  <div className="error" data-testid={`crs-error-${f}`} role="alert">
                    {errors[f]}
                  </div>
                )}
              </td>
            </tr>
          ))}
        </tbody>
      </table>
      <div className="row">
        <button className="primary" type="submit" data-testid="crs-save" disabled={busy || edits === null}>
          Save
        </button>
        <button
          type="button"
          data-testid="crs-clear"
          disabled={busy || stored === null}
          title="Remove the site's coordinates: positions in plan metres only"
          onClick={() => void send(CLEAR_CRS, "Cleared.")}
        >
          Clear
        </button>
        {edits !== null && (
          <button type="button" disabled={busy} onClick={() => (setEdits(null), setErrors({}), setGeneral(null))}>
            Revert
          </button>
        )}
        {status && (
          <span className="ok" data-testid="crs-status">
            {status}
          </span>
        )}
      </div>
      {general && (
        <p className="error" data-testid="crs-error" role="alert">
          {general}
        </p>
      )}
      {stored?.proj4 && (
        <p className="muted" style={{ fontSize: 11, wordBreak: "break-all" }} data-testid="crs-proj4">
          EPSG:{stored.epsg} = {stored.proj4}
        </p>
      )}
    </form>
  );
}

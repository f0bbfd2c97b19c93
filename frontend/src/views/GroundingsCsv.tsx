// The grounding workstation's CSV buttons: export the drive's groundings, import a groundings.csv that replaces
// them (editors only).
import { ApiError, apiDownload, apiPutForm, type Schemas } from "../api/client";

interface Props {
  drive: Schemas["DriveRead"] | null;
  editable: boolean;
  /** Show a line of status (what was imported, or the API's error). */
  say: (message: string) => void;
  /** After an import: ``replaced`` when the drive's groundings were replaced. */
  onImported: (replaced: boolean) => Promise<void>;
}

export function GroundingsCsv({ drive, editable, say, onImported }: Props) {
  const exportCsv = async () => {
    if (!drive) return;
    try {
      await apiDownload(`/api/drives/${drive.id}/groundings.csv`, `${drive.name}-groundings.csv`);
    } catch (e) {
      say(e instanceof ApiError ? e.message : String(e));
    }
  };

  const importCsv = async (file: File) => {
    if (!drive) return;
    const form = new FormData();
    form.append("file", file);
    let replaced = false;
    try {
      const result = await apiPutForm("/api/drives/{drive_id}/groundings.csv", { drive_id: drive.id }, form);
      say(`imported ${result.imported} groundings into ${drive.name} (replacing its old ones)`);
      replaced = true;
    } catch (e) {
      say(e instanceof ApiError ? e.message : String(e));
    }
    await onImported(replaced);
  };

  return (
    <>
      <button
        onClick={() => void exportCsv()}
        disabled={!drive}
        data-testid="export-csv"
        title="Export this drive's groundings"
      >
        CSV ↓
      </button>
      {editable && (
        <label
          className="filebutton"
          title={`Import groundings.csv into ${drive?.name ?? "the drive"} (replaces its groundings)`}
        >
          CSV ↑
          <input
            type="file"
            accept=".csv,text/csv"
            data-testid="import-csv"
            onChange={(e) => {
              const file = e.target.files?.[0];
              e.target.value = "";
              if (file) void importCsv(file);
            }}
          />
        </label>
      )}
    </>
  );
}

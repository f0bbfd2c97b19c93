// "Export" of a map version beside it on the grounding page: a version (the latest by default), a format, one
// drive or all (TUM and KITTI hold one drive), DXF's extra layers, and a download of
// GET /api/sites/{id}/maps/{version}/export with the login token; a refusal shows the server's reason.
import { useState } from "react";
import { buildUrl } from "../api/client";
import { MAP_FORMATS, type MapFormat } from "../lib/exports";
import { DownloadStatus, useDownload } from "./useDownload";

interface Props {
  siteId: number;
  /** The site's map versions (any order); nothing is shown without one. */
  versions: number[];
  /** The site's mapping drives' names. */
  drives: string[];
}

export function MapExport({ siteId, versions, drives }: Props) {
  const [picked, setPicked] = useState<number | null>(null);
  const [format, setFormat] = useState<MapFormat>("geojson");
  const [drive, setDrive] = useState(""); // "": every drive
  const [nodes, setNodes] = useState(false);
  const [closures, setClosures] = useState(false);
  const download = useDownload();
  if (versions.length === 0) return null;
  const sorted = [...versions].sort((a, b) => b - a);
  const version = picked !== null && versions.includes(picked) ? picked : sorted[0]!;
  const chosenDrive = drives.includes(drive) ? drive : "";
  const dxf = format === "dxf";

  const start = () => {
    const url = buildUrl(
      "/api/sites/{site_id}/maps/{version}/export",
      { site_id: siteId, version },
      {
        format,
        drive: chosenDrive || null,
        nodes: dxf && nodes ? true : null,
        closures: dxf && closures ? true : null,
      },
    );
    void download.run(url, `map-v${version}.${format}`);
  };

  return (
    <div className="export-box" data-testid="map-export">
      <div className="row">
        <span className="muted">Export</span>
        <select
          data-testid="map-export-version"
          value={version}
          onChange={(e) => setPicked(Number(e.target.value))}
          title="Map version"
        >
          {sorted.map((v) => (
            <option key={v} value={v}>
              v{v}
            </option>
          ))}
        </select>
        <select
          data-testid="map-export-format"
          value={format}
          onChange={(e) => setFormat(e.target.value as MapFormat)}
          title="File format (docs/formats.md, Exports)"
        >
          {Object.entries(MAP_FORMATS).map(([value, label]) => (
            <option key={value} value={value}>
              {label}
            </option>
          ))}
        </select>
        <select
          data-testid="map-export-drive"
          value={chosenDrive}
          onChange={(e) => setDrive(e.target.value)}
          title="Every mapping drive, or one (TUM and KITTI hold one)"
        >
          <option value="">all drives</option>
          {drives.map((d) => (
            <option key={d} value={d}>
              {d}
            </option>
          ))}
        </select>
        <button data-testid="map-export-download" onClick={start} disabled={download.busy}>
          {download.busy ? "Exporting…" : "Download"}
        </button>
      </div>
      {dxf && (
        <div className="row">
          <label title="The topological nodes and edges as a NODES layer">
            <input type="checkbox" checked={nodes} onChange={(e) => setNodes(e.target.checked)} /> nodes
          </label>
          <label title="Loop closures as CLOSURES and CLOSURES-REJECTED layers">
            <input type="checkbox" checked={closures} onChange={(e) => setClosures(e.target.checked)} /> loop closures
          </label>
        </div>
      )}
      <DownloadStatus download={download} testId="map-export" />
    </div>
  );
}

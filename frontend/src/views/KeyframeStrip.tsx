// The keyframe strip of the grounding workstation: the drive picker, play/pause, a page of keyframe thumbnails
// and the selected keyframe shown large.
import type { Schemas } from "../api/client";
import { driveColour, rgbCss } from "../lib/colours";
import { AuthImage } from "./AuthImage";

type Drive = Schemas["DriveRead"];

interface Props {
  drives: Drive[];
  driveId: number | null;
  onDrive: (id: number) => void;
  frames: number[];
  frame: number | null;
  onFrame: (frame: number) => void;
  page: number;
  pageCount: number;
  onPage: (page: number) => void;
  playing: boolean;
  onPlay: () => void;
  editable: boolean;
  /** The frames of the drive that are grounded (marked in the strip). */
  grounded: ReadonlySet<number>;
}

export function KeyframeStrip(props: Props) {
  const { drives, driveId, frames, frame, page, pageCount, playing, editable, grounded } = props;
  const drive = drives.find((d) => d.id === driveId) ?? null;
  return (
    <>
      <div className="row">
        <select
          data-testid="drive-select"
          value={driveId ?? ""}
          onChange={(e) => props.onDrive(Number(e.target.value))}
        >
          {drives.map((d) => (
            <option key={d.id} value={d.id}>
              {d.name} ({d.frame_count} frames)
            </option>
          ))}
        </select>
        {drive && <span className="dot" style={{ background: rgbCss(driveColour(drive.id)) }} />}
        <span className="spacer" />
        <button data-testid="play" onClick={props.onPlay} title="Play the drive's keyframes (space)">
          {playing ? "❚❚" : "▶"}
        </button>
        <button onClick={() => props.onPage(Math.max(0, page - 1))} disabled={page === 0}>
          ‹
        </button>
        <span className="muted">
          {page + 1}/{pageCount}
        </span>
        <button onClick={() => props.onPage(Math.min(pageCount - 1, page + 1))} disabled={page >= pageCount - 1}>
          ›
        </button>
      </div>
      <div className="strip" data-testid="keyframe-strip">
        {driveId !== null &&
          frames.map((f) => (
            <button
              key={f}
              className={`thumb ${f === frame ? "selected" : ""} ${grounded.has(f) ? "grounded" : ""}`}
              title={grounded.has(f) ? `frame ${f} (grounded)` : `frame ${f}`}
              data-testid={`keyframe-${f}`}
              data-frame={f}
              onClick={() => props.onFrame(f)}
            >
              <AuthImage src={`/api/drives/${driveId}/frames/${f}/thumbnail?width=96`} alt={`frame ${f}`} />
              <span>
                #{f}
                {grounded.has(f) ? " ■" : ""}
              </span>
            </button>
          ))}
      </div>
      {frame !== null && driveId !== null && (
        <div data-testid="selected-frame" data-frame={frame}>
          <AuthImage className="bigframe" src={`/api/drives/${driveId}/frames/${frame}`} alt={`frame ${frame} large`} />
          <div className="muted">
            {drive?.name} frame {frame}
            {grounded.has(frame) ? " (grounded)" : ""}
            {editable ? " · Place (g), then click its surveyed point on the plan; drag a square to adjust one" : ""}
          </div>
        </div>
      )}
    </>
  );
}

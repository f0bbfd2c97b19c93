// The keyframe strip of the grounding workstation: the drive picker, play/pause, a page of keyframe thumbnails
// (scrolled to the selected one), a slider over every frame of the drive and "go to frame" (any frame can be
// grounded, not only the strip's keyframes), and the selected frame shown large.
import { useEffect, useRef, useState } from "react";
import type { Schemas } from "../api/client";
import { parseFrame } from "../lib/frameNav";
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
  /** Open the selected frame large beside the plan. */
  onLarge: () => void;
  /** The frames of the drive that are grounded (marked in the strip). */
  grounded: ReadonlySet<number>;
}

export function KeyframeStrip(props: Props) {
  const { drives, driveId, frames, frame, page, pageCount, playing, editable, grounded } = props;
  const drive = drives.find((d) => d.id === driveId) ?? null;
  const strip = useRef<HTMLDivElement>(null);
  const [typed, setTyped] = useState("");
  const [gotoError, setGotoError] = useState<string | null>(null);

  useEffect(() => {
    // the strip follows the selection: its thumbnail scrolled into view (a frame between keyframes has none)
    strip.current?.querySelector(".thumb.selected")?.scrollIntoView({ block: "nearest", inline: "nearest" });
  }, [frame, frames]);

  const goto = () => {
    if (!drive) return;
    const parsed = parseFrame(typed, drive.frame_count);
    if ("error" in parsed) {
      setGotoError(parsed.error);
      return;
    }
    setGotoError(null);
    props.onFrame(parsed.frame);
  };

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
      {drive && drive.frame_count > 0 && (
        <div className="row">
          <input
            type="range"
            className="grow"
            data-testid="frame-slider"
            aria-label="frame"
            min={0}
            max={drive.frame_count - 1}
            value={frame ?? 0}
            onChange={(e) => props.onFrame(Number(e.target.value))}
          />
          <form
            className="row"
            onSubmit={(e) => {
              e.preventDefault();
              goto();
            }}
          >
            <input
              data-testid="goto-frame"
              aria-label="go to frame"
              placeholder="frame"
              size={5}
              value={typed}
              onChange={(e) => setTyped(e.target.value)}
            />
            <button type="submit" data-testid="goto-frame-button">
              Go
            </button>
          </form>
        </div>
      )}
      {gotoError && (
        <div className="error" data-testid="goto-frame-error">
          {gotoError}
        </div>
      )}
      <div className="strip" data-testid="keyframe-strip" ref={strip}>
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
            <button data-testid="frame-large" onClick={props.onLarge} title="The frame large beside the plan">
              Large view
            </button>{" "}
            {drive?.name} frame {frame}
            {grounded.has(frame) ? " (grounded)" : ""}
            {editable ? " · Place (g), then click its surveyed point on the plan; drag a square to adjust one" : ""}
          </div>
        </div>
      )}
    </>
  );
}

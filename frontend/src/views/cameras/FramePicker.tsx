// The floor frames of the session: upload PNG/JPEG files (or take a photo on a device with a camera) and pick
// the one to show large. The files stay in the browser (object URLs); only the previews send the picked one to
// the server, which keeps nothing.
export interface Frame {
  name: string;
  url: string;
}

interface Props {
  frames: Frame[];
  selected: number;
  onAdd: (files: File[]) => void;
  onSelect: (index: number) => void;
}

const IMAGE_TYPES = "image/png,image/jpeg";

export function FramePicker({ frames, selected, onAdd, onSelect }: Props) {
  const add = (list: FileList | null) => {
    const files = Array.from(list ?? []).filter(
      (f) => f.type === "image/png" || f.type === "image/jpeg" || /\.(png|jpe?g)$/i.test(f.name),
    );
    if (files.length > 0) onAdd(files);
  };
  return (
    <div>
      <div className="row">
        <label className="filebutton" title="PNG or JPEG frames of the camera looking at the floor">
          Upload frames…
          <input
            type="file"
            multiple
            accept={IMAGE_TYPES}
            data-testid="camera-frames-input"
            onChange={(e) => {
              add(e.target.files);
              e.target.value = "";
            }}
          />
        </label>
        <label className="filebutton" title="Take a photo with this device's camera">
          Take one…
          <input
            type="file"
            accept={IMAGE_TYPES}
            capture="environment"
            onChange={(e) => {
              add(e.target.files);
              e.target.value = "";
            }}
          />
        </label>
        {frames.length === 0 && <span className="muted">No frame yet.</span>}
      </div>
      {frames.length > 1 && (
        <div className="strip camthumbs" data-testid="camera-frames">
          {frames.map((f, i) => (
            <button
              key={f.url}
              className={`thumb${i === selected ? " selected" : ""}`}
              title={f.name}
              onClick={() => onSelect(i)}
            >
              <img src={f.url} alt={f.name} />
              <span>{f.name}</span>
            </button>
          ))}
        </div>
      )}
    </div>
  );
}

// The residual table's drive filter and the RMS, mean and max grounding residual (metres) of the latest
// build, per drive and overall, over the groundings the build used (GET .../maps/{v}/residuals/summary).
import type { Schemas } from "../api/client";

type Summary = Schemas["ResidualSummaryRead"];
type Stats = Schemas["ResidualStatsRead"];

interface Props {
  summary: Summary | null;
  drives: Schemas["DriveRead"][];
  /** The drive the table shows (null: every drive); the summary shows its line and the overall one. */
  driveId: number | null;
  onDrive: (driveId: number | null) => void;
}

function Line({ name, stats }: { name: string; stats: Stats }) {
  return (
    <tr data-testid={`residual-summary-${name}`}>
      <td>{name}</td>
      <td className="num">{stats.count}</td>
      <td className="num">{stats.rms_m.toFixed(2)}</td>
      <td className="num">{stats.mean_m.toFixed(2)}</td>
      <td className="num">{stats.max_m.toFixed(2)}</td>
    </tr>
  );
}

export function ResidualSummary({ summary, drives, driveId, onDrive }: Props) {
  const drive = drives.find((d) => d.id === driveId)?.name ?? null;
  const lines = summary ? summary.drives.filter((d) => drive === null || d.drive === drive) : [];
  return (
    <>
      <label>
        Drive{" "}
        <select
          data-testid="grounding-drive-filter"
          value={driveId ?? ""}
          onChange={(e) => onDrive(e.target.value === "" ? null : Number(e.target.value))}
        >
          <option value="">all</option>
          {drives.map((d) => (
            <option key={d.id} value={d.id}>
              {d.name}
            </option>
          ))}
        </select>
      </label>
      {summary && <SummaryTable summary={summary} lines={lines} />}
    </>
  );
}

function SummaryTable({ summary, lines }: { summary: Summary; lines: Summary["drives"] }) {
  return (
    <table data-testid="residual-summary" title={`Residuals of map version ${summary.version}, metres`}>
      <thead>
        <tr>
          <th>v{summary.version}</th>
          <th className="num">n</th>
          <th className="num">RMS m</th>
          <th className="num">mean m</th>
          <th className="num">max m</th>
        </tr>
      </thead>
      <tbody>
        {lines.map((d) => (
          <Line key={d.drive} name={d.drive} stats={d.stats} />
        ))}
        <Line name="all" stats={summary.overall} />
      </tbody>
    </table>
  );
}

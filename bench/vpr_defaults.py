"""The defaults of ``driftmap vpr match --temporal`` on frames they were tuned on and on frames they were not.

Nordland-1000 (``../shared/data/nordland-1000``: summer references, winter queries, gt +-1 frame) is split in
two routes of its own: **tune** = frames 0-499 (references and queries), **held out** = frames 500-999. Every
setting of ``core.place_recognition.route`` (and the calibration knots of ``ROUTE_DEFAULT``) was chosen on the tuning
part only; the held-out part and the corridor (111 x 111 indoor frames, gt +-2, out of domain) are only
measured. Sections, each printed as a table (the tables of ``docs/evaluation/place_recognition.md``):

* ``table``: old defaults (SESAME, preset mine, causal filter, raw score), ``--method sad --preset route``
  with the causal filter, the new defaults (``ROUTE_DEFAULT``: SAD, preset route, forward-backward,
  calibration knots), SeqSLAM (``bench/seqslam.py``, OpenSeqSLAM's defaults on the same difference
  matrix), and the new defaults with ``--method sesame`` or ``--any-speed``: recall@1, AUC, recall at
  100 % precision, seconds (images decoded beforehand) and the score's expected calibration error (ECE,
  10 bins).
* ``score``: the window posterior against it times the matched reference's distinctness along the
  sequence (the mine localiser's ``score x distinct``), smoothed and causal, on the tuning part.
* ``calibration``: the logistic fit on the tuning part that gives ``ROUTE_DEFAULT.calibration``, against
  the raw posterior and an isotonic fit (``core.place_recognition.metrics.fit_calibration``), by ECE on every part.
* ``sensitivity``: AUC / recall at 100 % precision over gain x mix x score window and over reach, on the
  tuning part (the choice) and the held-out part (for the record, not the choice).
* ``speed``: the query traversal at 0.5x, 1.5x and 2x the references' speed (every 2nd reference; 2 of
  every 3 queries; every 2nd query): the fixed speed prior of the defaults against ``--any-speed`` and
  SeqSLAM (whose velocities span 0.8-1.2).

Writes ``docs/vpr_defaults.png`` (held-out precision-recall; reliability of the new defaults' score).
Skips cleanly (exit 0) when the data folder is absent. Usage:
``.venv/bin/python bench/vpr_defaults.py [--data ../shared/data] [--sections table,calibration,...]``
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

from driftmap.core.place_recognition import metrics
from driftmap.core.place_recognition import route as vpr_route
from driftmap.core.place_recognition import single as vpr
from driftmap.core.place_recognition.route_filter import ROUTE_ANY_SPEED, ROUTE_DEFAULT, RouteParams
from driftmap.core.place_recognition.single import Matches
from driftmap.formats.place_images import gt_matrix, list_images, read_gray_stack, read_gt_pairs
from seqslam import seqslam

ROOT = Path(__file__).resolve().parents[1]
U8 = NDArray[np.uint8]
BoolArr = NDArray[np.bool_]
IDENTITY = ((0.0, 0.0), (1.0, 1.0))
#: ``driftmap vpr match --temporal`` before: SESAME, shifts +-4/+-2 px, the causal filter, raw belief.
OLD = replace(ROUTE_DEFAULT, smooth=False, calibration=IDENTITY)
SECTIONS = ("table", "score", "calibration", "sensitivity", "speed")


@dataclass(frozen=True)
class Part:
    """One dataset (or split) and what every run on it shares."""

    name: str
    query: U8
    db: U8
    gt: BoolArr
    d: NDArray[np.float32]  # (Q, D) driftmap's SAD distances, preset route
    ref_median: NDArray[np.float64]
    ref_scale: NDArray[np.float64]


def load(folder: Path) -> tuple[U8, U8, BoolArr]:
    db_files, q_files = list_images(folder / "db"), list_images(folder / "query")
    gt = gt_matrix(read_gt_pairs(folder / "gt.csv", q_files, db_files), q_files, db_files)
    return read_gray_stack(q_files), read_gray_stack(db_files), gt


def part(name: str, query: U8, db: U8, gt: BoolArr) -> Part:
    pq, pd = vpr.prepare_images(query, "sad", vpr.VPR_ROUTE), vpr.prepare_images(db, "sad", vpr.VPR_ROUTE)
    m, s = vpr_route.reference_model(pd, vpr.VPR_ROUTE)
    return Part(name, query, db, gt, vpr.distance_matrix(pq, pd, vpr.VPR_ROUTE), m, s)


def parts(data: Path) -> list[Part]:
    query, db, gt = load(data / "nordland-1000")
    out = [
        part("Nordland 0-499 (tune)", query[:500], db[:500], gt[:500, :500]),
        part("Nordland 500-999 (held out)", query[500:], db[500:], gt[500:, 500:]),
    ]
    if (data / "corridor" / "gt.csv").is_file():
        out.append(part("corridor (out of domain)", *load(data / "corridor")))
    return out


def scored(m: Matches, gt: BoolArr) -> tuple[metrics.PlaceMetrics, metrics.PrCurve, float]:
    result, curve = metrics.evaluate_matches(m.db_index, m.score, gt)
    ece = metrics.reliability(m.score, metrics.match_correct(m.db_index, gt)).expected_calibration_error
    return result, curve, ece


def timed(run: Callable[[], Matches]) -> tuple[Matches, float]:
    t0 = time.perf_counter()
    m = run()
    return m, time.perf_counter() - t0


def run_seqslam(p: Part) -> Matches:
    pq, pd = vpr.prepare_images(p.query, "sad", vpr.VPR_ROUTE), vpr.prepare_images(p.db, "sad", vpr.VPR_ROUTE)
    return seqslam(vpr.distance_matrix(pq, pd, vpr.VPR_ROUTE))


def table(ps: list[Part]) -> dict[str, dict[str, tuple[Matches, metrics.PrCurve]]]:
    runs: dict[str, Callable[[Part], Matches]] = {
        "old defaults (sesame, mine, filter)": lambda p: vpr_route.recognise_places(
            p.query, p.db, "sesame", temporal=True, params=vpr.VPR_DEFAULT, route=OLD
        ),
        "--method sad --preset route (filter)": lambda p: vpr_route.recognise_places(
            p.query, p.db, "sad", temporal=True, params=vpr.VPR_ROUTE, route=OLD
        ),
        "new defaults": lambda p: vpr_route.recognise_places(
            p.query, p.db, "sad", temporal=True, params=vpr.VPR_ROUTE, route=ROUTE_DEFAULT
        ),
        "SeqSLAM (bench/seqslam.py)": run_seqslam,
        "new defaults with --method sesame": lambda p: vpr_route.recognise_places(
            p.query, p.db, "sesame", temporal=True, params=vpr.VPR_ROUTE, route=ROUTE_DEFAULT
        ),
        "new defaults with --any-speed": lambda p: vpr_route.recognise_places(
            p.query, p.db, "sad", temporal=True, params=vpr.VPR_ROUTE, route=ROUTE_ANY_SPEED
        ),
    }
    kept: dict[str, dict[str, tuple[Matches, metrics.PrCurve]]] = {}
    print("\n## table: recall@1 / AUC / recall at 100 % precision / seconds / ECE of the score")
    print(f"| part | run | recall@1 | AUC | R@100P | seconds | ECE |\n|{'---|' * 7}")
    for p in ps:
        kept[p.name] = {}
        for label, run in runs.items():
            m, seconds = timed(lambda run=run, p=p: run(p))  # type: ignore[misc]
            r, curve, ece = scored(m, p.gt)
            kept[p.name][label] = (m, curve)
            print(
                f"| {p.name} | {label} | {r.recall_at_1:.3f} | {r.auc:.3f} | "
                f"{r.recall_at_full_precision:.3f} | {seconds:.1f} | {ece:.3f} |",
                flush=True,
            )
    return kept


def running_mean(x: NDArray[np.float64], memory: float) -> NDArray[np.float64]:
    """Exponential running average with weight ``memory`` on the newest value (the localiser's track)."""
    out = np.empty_like(x)
    acc = 0.0
    for i, v in enumerate(x):
        acc = (1.0 - memory) * acc + memory * v
        out[i] = acc
    return out


def centred_mean(x: NDArray[np.float64], half: int) -> NDArray[np.float64]:
    """Mean over the frames within ``+-half`` of each (fewer at the ends)."""
    kernel = np.ones(2 * half + 1)
    return np.convolve(x, kernel, "same") / np.convolve(np.ones_like(x), kernel, "same")


def score(ps: list[Part]) -> None:
    tune = ps[0]
    rows = np.arange(tune.d.shape[0])
    print(f"\n## score: AUC / recall at 100 % precision on {tune.name} (recall@1 is the same in a row)")
    print(f"| score | smoothed (default) | causal filter |\n|{'---|' * 3}")
    runs = {
        mode: raw_run(tune, replace(ROUTE_DEFAULT, smooth=mode == "smooth")) for mode in ("smooth", "online")
    }
    variants: dict[str, Callable[[Matches], NDArray[np.float64]]] = {}
    variants["window posterior (default)"] = lambda m: m.score

    def typical(m: Matches) -> NDArray[np.float64]:  # 1 - d(b) / median d: the localiser's frame distinctness
        d = tune.d.astype(np.float64)
        return np.clip(1.0 - d[rows, m.db_index] / np.median(d, axis=1), 0.0, 1.0)

    def elsewhere(m: Matches) -> NDArray[np.float64]:  # 1 - d(b) / least d more than 5 references away
        d = tune.d.astype(np.float64)
        far = np.abs(np.arange(d.shape[1])[None, :] - m.db_index[:, None]) > 5
        return np.clip(1.0 - d[rows, m.db_index] / np.where(far, d, np.inf).min(axis=1), 0.0, 1.0)

    variants["x typical distinctness, running (memory 0.2)"] = lambda m: (
        m.score * running_mean(typical(m), 0.2)
    )
    variants["x elsewhere distinctness, running (memory 0.2)"] = lambda m: (
        m.score * running_mean(elsewhere(m), 0.2)
    )
    variants["x elsewhere distinctness, mean over +-5 frames"] = lambda m: (
        m.score * centred_mean(elsewhere(m), 5)
    )
    variants["elsewhere distinctness alone, mean over +-5 frames"] = lambda m: centred_mean(elsewhere(m), 5)
    for label, variant in variants.items():
        cells = []
        for m in runs.values():
            r, _ = metrics.evaluate_matches(m.db_index, variant(m), tune.gt)
            cells.append(f"{r.auc:.3f} / {r.recall_at_full_precision:.3f}")
        print(f"| {label} | {' | '.join(cells)} |")


def fit_logistic(raw: NDArray[np.float64], right: BoolArr) -> tuple[float, float]:
    """``(a, b)`` of ``P(right) = 1 / (1 + exp(-(a logit(raw) + b)))`` by maximum likelihood."""
    x = logit(raw)
    y = right.astype(np.float64)

    def nll(ab: NDArray[np.float64]) -> float:
        z = ab[0] * x + ab[1]
        return float(np.sum(np.logaddexp(0.0, z) - y * z))

    a, b = minimize(nll, np.array([1.0, 0.0]), method="Nelder-Mead").x
    return float(a), float(b)


def logit(p: NDArray[np.float64]) -> NDArray[np.float64]:
    q = np.clip(p, 1e-6, 1.0 - 1e-6)
    return np.asarray(np.log(q / (1.0 - q)))


def logistic_knots(a: float, b: float, count: int = 11) -> tuple[tuple[float, float], ...]:
    """The logistic read off at ``count`` evenly spaced raw values, ends pinned to (0, 0) and (1, 1)."""
    grid = np.linspace(0.0, 1.0, count)
    values = 1.0 / (1.0 + np.exp(-(a * logit(grid) + b)))
    values[0], values[-1] = 0.0, 1.0
    return tuple((round(float(g), 2), float(f"{v:.3g}")) for g, v in zip(grid, values, strict=True))


def raw_run(p: Part, route: RouteParams = ROUTE_DEFAULT) -> Matches:
    return vpr_route.match_distances(p.d, p.ref_median, p.ref_scale, replace(route, calibration=IDENTITY))


def calibration(ps: list[Part]) -> None:
    tune = ps[0]
    raw = raw_run(tune)
    right = metrics.match_correct(raw.db_index, tune.gt)
    a, b = fit_logistic(raw.score, right)
    knots = logistic_knots(a, b)
    isotonic = metrics.fit_calibration(raw.score, right)
    print(f"\n## calibration: logistic fit on {tune.name}: a = {a:.3f}, b = {b:.3f}")
    print(f"knots: {knots}")
    print(f"ROUTE_DEFAULT.calibration = {ROUTE_DEFAULT.calibration}")
    print(f"isotonic (fit_calibration): {tuple((round(x, 2), round(y, 3)) for x, y in isotonic)}")
    print("ECE / Brier score / recall at 100 % precision of the score, mapped through each calibration:")
    print(f"| part | raw posterior (default) | isotonic | logistic |\n|{'---|' * 4}")
    for p in ps:
        m = raw_run(p)
        right_p = metrics.match_correct(m.db_index, p.gt)
        cells = []
        for k in (IDENTITY, isotonic, knots):
            mapped = vpr_route.calibrated(m.score, k)
            rel = metrics.reliability(mapped, right_p)
            r, _ = metrics.evaluate_matches(m.db_index, mapped, p.gt)
            brier = float(np.mean((mapped - right_p) ** 2))
            cells.append(
                f"{rel.expected_calibration_error:.3f} / {brier:.3f} / {r.recall_at_full_precision:.3f}"
            )
        print(f"| {p.name} | {' | '.join(cells)} |")


def sensitivity(ps: list[Part]) -> None:
    print(
        "\n## sensitivity: AUC / recall at 100 % precision (reach 2; the default: gain 0.5, mix 0.003, window 2)"
    )
    for p in ps[:2]:
        print(f"\n{p.name}\n| gain | mix | window 1 | window 2 | window 3 |\n|{'---|' * 5}")
        summary = []
        for gain in (0.25, 0.35, 0.5, 0.75, 1.0):
            for mix in (0.001, 0.003, 0.01, 0.03):
                cells = []
                for window in (1, 2, 3):
                    route = replace(ROUTE_DEFAULT, gain=gain, uniform_mix=mix, score_window_frames=window)
                    r, _, _ = scored(raw_run(p, route), p.gt)
                    cells.append(f"{r.auc:.3f} / {r.recall_at_full_precision:.3f}")
                    if 0.35 <= gain <= 0.75 and mix <= 0.01:
                        summary.append((r.auc, r.recall_at_full_precision))
                print(f"| {gain} | {mix} | {' | '.join(cells)} |", flush=True)
        s = np.array(summary)
        print(
            f"gain 0.35-0.75, mix 0.001-0.01, window 1-3: AUC {s[:, 0].min():.3f}-{s[:, 0].max():.3f}, "
            f"R@100P {s[:, 1].min():.3f}-{s[:, 1].max():.3f}"
        )
        cells = []
        for reach in (1, 2, 3):
            r, _, _ = scored(raw_run(p, replace(ROUTE_DEFAULT, reach_frames=reach)), p.gt)
            cells.append(f"reach {reach}: {r.auc:.3f} / {r.recall_at_full_precision:.3f}")
        print("; ".join(cells))


def speed(ps: list[Part]) -> None:
    print(
        "\n## speed: AUC / recall at 100 % precision when the query runs at another speed than the references"
    )
    print(f"| part | run | 1x | 0.5x | 1.5x | 2x |\n|{'---|' * 6}")
    for p in ps[:2]:
        nq, nd = p.d.shape
        cases = {
            "1x": (np.arange(nq), np.arange(nd)),
            "0.5x": (np.arange(nq), np.arange(0, nd, 2)),
            "1.5x": (np.flatnonzero(np.arange(nq) % 3 != 2), np.arange(nd)),
            "2x": (np.arange(0, nq, 2), np.arange(nd)),
        }
        routes = {
            "new defaults": ROUTE_DEFAULT,
            "new defaults, gain 0.25": replace(ROUTE_DEFAULT, gain=0.25),
            "--any-speed": ROUTE_ANY_SPEED,
        }
        for label in (*routes, "SeqSLAM"):
            cells = []
            for qi, dj in cases.values():
                d, gt = p.d[np.ix_(qi, dj)], p.gt[np.ix_(qi, dj)]
                if label == "SeqSLAM":
                    m = seqslam(d)
                else:
                    ref_median, ref_scale = vpr_route.reference_model(
                        vpr.prepare_images(p.db[dj], "sad", vpr.VPR_ROUTE), vpr.VPR_ROUTE, routes[label]
                    )
                    m = vpr_route.match_distances(d, ref_median, ref_scale, routes[label])
                r, _, _ = scored(m, gt)
                cells.append(f"{r.auc:.3f} / {r.recall_at_full_precision:.3f}")
            print(f"| {p.name} | {label} | {' | '.join(cells)} |", flush=True)


def figure(ps: list[Part], kept: dict[str, dict[str, tuple[Matches, metrics.PrCurve]]], path: Path) -> None:
    fig, (ax_pr, ax_rel) = plt.subplots(1, 2, figsize=(11.0, 4.6))
    held = ps[1]
    for label, (_, curve) in kept[held.name].items():
        if label.startswith(("--method", "new defaults with")):
            continue
        ax_pr.step(
            np.r_[0.0, curve.recall],
            np.r_[curve.precision[:1], curve.precision],
            label=f"{label}: AUC {curve.auc:.3f}, R@100P {curve.recall_at_full_precision:.3f}",
        )
    ax_pr.set(xlabel="recall", ylabel="precision", xlim=(0, 1), ylim=(0, 1.02), title=f"{held.name}")
    ax_pr.legend(fontsize=7, loc="lower left")
    ax_rel.plot([0, 1], [0, 1], "k:", lw=1, label="perfectly calibrated")
    for p in ps:
        m, _ = kept[p.name]["new defaults"]
        rel = metrics.reliability(m.score, metrics.match_correct(m.db_index, p.gt))
        ok = rel.counts > 0
        ax_rel.plot(
            rel.mean_confidence[ok],
            rel.right_share[ok],
            "o-",
            label=f"{p.name}: ECE {rel.expected_calibration_error:.3f}",
        )
    ax_rel.set(
        xlabel="reported score (bin mean)",
        ylabel="share of matches right",
        xlim=(0, 1),
        ylim=(0, 1.02),
        title="new defaults: reliability (10 bins)",
    )
    ax_rel.legend(fontsize=7, loc="upper left")
    for ax in (ax_pr, ax_rel):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"\nfigure: {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument(
        "--sections", default=",".join(SECTIONS), help=f"comma-separated: {', '.join(SECTIONS)}"
    )
    args = parser.parse_args()
    if not (args.data / "nordland-1000" / "gt.csv").is_file():
        print(f"skipped: no Nordland data under {args.data}")
        return
    sections = set(args.sections.split(","))
    ps = parts(args.data)
    if "table" in sections:
        figure(ps, table(ps), ROOT / "docs" / "vpr_defaults.png")
    if "score" in sections:
        score(ps)
    if "calibration" in sections:
        calibration(ps)
    if "sensitivity" in sections:
        sensitivity(ps)
    if "speed" in sections:
        speed(ps)


if __name__ == "__main__":
    main()

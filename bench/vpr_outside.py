"""Place recognition on the outside datasets: single-image SAD / SESAME and the route HMM, with PR curves.

Datasets (``../shared/data``, see its README): ``corridor`` (111 vs 111 indoor images, gt +-2 frames) and
``nordland-1000`` (summer references vs winter queries, first 1,000 of the 64x32 sample, gt +-1 frame).
For each, in one process: the baseline (plain patch-normalised SAD, single image), SESAME single image,
``--temporal`` (the route HMM of ``driftmap.core.place_recognition.route``, smoothed over the whole query sequence) with SAD
and with SESAME, the same with ``--online`` (the causal filter) and with ``--any-speed``, the paper's HMM
exactly as the mine localiser runs it (``core.localisation.localiser.Localiser`` on a chain map, eq. 8 observation), and
SeqSLAM (``bench/seqslam.py``, OpenSeqSLAM's defaults on the SAD difference matrix) for comparison. A second
table drops every other query (the query traversal then runs twice as fast as the references') to show the
speed prior of the default HMM. Prints
recall@1, AUC, recall at 100 % precision and wall seconds (images decoded beforehand; thumbnails, masks,
distances and the filter counted), the ratio of each to the baseline, and the reference figures measured
outside this project. Writes ``docs/vpr_corridor.png`` and ``docs/vpr_nordland.png``.

Presets (``driftmap.core.place_recognition.single.VPR_PRESETS``): ``mine`` searches shifts of +-4/+-2 px like the mine localiser;
``route`` does not search shifts (a camera on a fixed path). Nordland's single-image runs use ``route``
only, ``--mine-nordland`` adds the ``mine`` ones (about a minute each on a busy 2-core machine).

Skips cleanly (exit 0) when the data folder is absent. Usage:
``.venv/bin/python bench/vpr_outside.py [--data ../shared/data] [--workers 1] [--mine-nordland]``
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_array

from driftmap.core.localisation import hmm
from driftmap.core.localisation.localiser import Localiser
from driftmap.core.localisation.map import LocaliserMap
from driftmap.core.place_recognition import metrics
from driftmap.core.place_recognition.route import recognise_places
from driftmap.core.place_recognition.route_filter import (
    ROUTE_ANY_SPEED,
    ROUTE_DEFAULT,
    ROUTE_ONLINE,
    RouteParams,
)
from driftmap.core.place_recognition.single import (
    VPR_PRESETS,
    Matches,
    VprMethod,
    VprParams,
    distance_matrix,
    prepare_images,
)
from driftmap.formats.place_images import gt_matrix, list_images, read_gray_stack, read_gt_pairs
from seqslam import seqslam

ROOT = Path(__file__).resolve().parents[1]
#: Figures measured outside this project on the same frames (issue 4).
REFERENCES = {
    "corridor": ["SAD single image (outside): recall@1 0.414"],
    "nordland-1000": [
        "SAD single image (outside): recall@1 0.176",
        "SeqSLAM (outside, +-1 frame): AUC 0.727, recall at 100% precision 0.57, 44 s on 2 cores",
    ],
}
PNG = {"corridor": "vpr_corridor.png", "nordland-1000": "vpr_nordland.png"}


@dataclass(frozen=True)
class Run:
    """One configuration of one dataset."""

    label: str
    method: VprMethod
    temporal: bool
    preset: str
    route: RouteParams = ROUTE_DEFAULT
    localiser: bool = False  # the mine localiser's HMM (eq. 8) on a chain map instead of the route HMM
    seqslam: bool = False  # SeqSLAM on the SAD difference matrix instead of the route HMM


@dataclass(frozen=True)
class Outcome:
    run: Run
    result: metrics.PlaceMetrics
    curve: metrics.PrCurve
    seconds: float


def runs(dataset: str, mine_nordland: bool) -> list[Run]:
    """The baseline first, then SESAME and the route HMM."""
    single_presets = ["route"] if dataset == "nordland-1000" and not mine_nordland else ["mine", "route"]
    out = []
    for preset in single_presets:
        out.append(Run(f"SAD single ({preset})", "sad", False, preset))
        out.append(Run(f"SESAME single ({preset})", "sesame", False, preset))
    out.append(Run("route HMM + SAD (route)", "sad", True, "route"))
    out.append(Run("route HMM + SESAME (route)", "sesame", True, "route"))
    out.append(Run("  online, SAD", "sad", True, "route", ROUTE_ONLINE))
    out.append(Run("  online, SESAME", "sesame", True, "route", ROUTE_ONLINE))
    out.append(Run("  any speed, SAD", "sad", True, "route", ROUTE_ANY_SPEED))
    out.append(Run("  any speed, SESAME", "sesame", True, "route", ROUTE_ANY_SPEED))
    out.append(Run("paper HMM (Localiser), SAD", "sad", True, "route", localiser=True))
    out.append(Run("SeqSLAM (bench/seqslam.py)", "sad", True, "route", seqslam=True))
    return out


def speed_runs() -> list[Run]:
    return [
        Run("route HMM + SAD (2x speed)", "sad", True, "route"),
        Run("  any speed, SAD (2x speed)", "sad", True, "route", ROUTE_ANY_SPEED),
        Run("SeqSLAM (2x speed)", "sad", True, "route", seqslam=True),
    ]


def chain_localiser(query: NDArray[np.uint8], db: NDArray[np.uint8], params: VprParams) -> Matches:
    """The mine localiser (paper eq. 4-12 as in ``core.localisation.localiser``) over the references as a chain map."""
    pq, pd = prepare_images(query, "sad", params), prepare_images(db, "sad", params)
    n, k_max = pd.thumbs.shape[0], 64
    rows, cols, vals = [], [], []
    for k in range(1, k_max + 1):
        j = np.arange(n - k, dtype=np.int64)
        rows += [j, j + k]
        cols += [j + k, j]
        vals += [np.full(j.size, float(k))] * 2
    adjacency = csr_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    lmap = LocaliserMap(
        thumbs=pd.thumbs,
        node_ptr=np.arange(n + 1, dtype=np.int64),
        centres_m=np.column_stack([np.arange(n, dtype=np.float64), np.zeros(n)]),
        adjacency_m=adjacency,
        max_adjacency_m=float(k_max),
    )
    # distances in frames, one query frame per "second": A_t = 3 reaches 2 references per frame
    chain = replace(hmm.PAPER, max_speed_mps=3.0, min_a_t_m=3.0, a_t_quantum_m=1.0)
    loc = Localiser(lmap, chain, params.sad)
    steps = [loc.step(thumb, float(i)) for i, thumb in enumerate(pq.thumbs)]
    return Matches(
        db_index=np.array([e.node for e in steps], dtype=np.int64),
        score=np.array([e.score for e in steps], dtype=np.float64),
    )


def load(folder: Path) -> tuple[NDArray[np.uint8], NDArray[np.uint8], NDArray[np.bool_]]:
    """Query images, reference images and the (Q, D) ground-truth table of a dataset folder."""
    db_files, q_files = list_images(folder / "db"), list_images(folder / "query")
    gt = gt_matrix(read_gt_pairs(folder / "gt.csv", q_files, db_files), q_files, db_files)
    return read_gray_stack(q_files), read_gray_stack(db_files), gt


def execute(
    runs_: list[Run], query: NDArray[np.uint8], db: NDArray[np.uint8], gt: NDArray[np.bool_], workers: int
) -> list[Outcome]:
    """Run each configuration, timed (prepare, distances and matching; images decoded beforehand)."""
    outcomes = []
    for run in runs_:
        t0 = time.perf_counter()
        if run.localiser:
            m = chain_localiser(query, db, VPR_PRESETS[run.preset])
        elif run.seqslam:
            params = VPR_PRESETS[run.preset]
            pq, pd = prepare_images(query, "sad", params), prepare_images(db, "sad", params)
            m = seqslam(distance_matrix(pq, pd, params))
        else:
            m = recognise_places(
                query,
                db,
                run.method,
                temporal=run.temporal,
                params=VPR_PRESETS[run.preset],
                route=run.route,
                workers=workers,
            )
        seconds = time.perf_counter() - t0
        result, curve = metrics.evaluate_matches(m.db_index, m.score, gt)
        outcomes.append(Outcome(run, result, curve, seconds))
    return outcomes


def report(outcomes: list[Outcome]) -> None:
    base = outcomes[0]
    print(f"{'run':<28} {'recall@1':>9} {'AUC':>7} {'R@100P':>7} {'seconds':>8}   vs {base.run.label}")
    for o in outcomes:
        r = o.result
        ratio = (r.auc / base.result.auc) if base.result.auc > 0 else float("inf")
        print(
            f"{o.run.label:<28} {r.recall_at_1:9.3f} {r.auc:7.3f} {r.recall_at_full_precision:7.3f} "
            f"{o.seconds:8.1f}   AUC x{ratio:.1f}, recall@1 {r.recall_at_1 - base.result.recall_at_1:+.3f}"
        )


def evaluate(dataset: str, folder: Path, workers: int, mine_nordland: bool) -> list[Outcome]:
    query, db, gt = load(folder)
    print(
        f"\n== {dataset}: {query.shape[0]} queries x {db.shape[0]} references, {db.shape[2]}x{db.shape[1]} px"
    )
    outcomes = execute(runs(dataset, mine_nordland), query, db, gt, workers)
    report(outcomes)
    for line in REFERENCES[dataset]:
        print(f"  reference: {line}")
    print(f"-- {dataset}, every other query (the queries run at twice the references' speed)")
    report(execute(speed_runs(), query[::2], db, gt[::2], workers))
    return outcomes


def plot(dataset: str, outcomes: list[Outcome], path: Path) -> None:
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    for o in outcomes:
        if o.run.localiser or o.run.route is not ROUTE_DEFAULT:
            continue  # the figure keeps to the main runs (and SeqSLAM)
        style = "-" if o.run.temporal else "--"
        label = f"{o.run.label}: AUC {o.result.auc:.2f}"
        ax.step(
            np.r_[0.0, o.curve.recall], np.r_[o.curve.precision[:1], o.curve.precision], style, label=label
        )
    if dataset == "nordland-1000":
        ax.plot([0.57], [1.0], "k*", markersize=10, label="SeqSLAM (outside): R@100P 0.57, AUC 0.727")
    ax.set_xlabel("recall")
    ax.set_ylabel("precision")
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1.02)
    ax.set_title(f"{dataset}: place recognition, precision-recall")
    ax.legend(fontsize=7, loc="lower left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"  figure: {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--workers", type=int, default=1, help="threads computing image distances")
    parser.add_argument(
        "--mine-nordland", action="store_true", help="also the +-4/+-2 shift runs on Nordland"
    )
    args = parser.parse_args()
    present = [d for d in PNG if (args.data / d / "gt.csv").is_file()]
    if not present:
        print(f"skipped: no outside data under {args.data}")
        return
    for dataset in present:
        outcomes = evaluate(dataset, args.data / dataset, args.workers, args.mine_nordland)
        plot(dataset, outcomes, ROOT / "docs" / PNG[dataset])


if __name__ == "__main__":
    main()

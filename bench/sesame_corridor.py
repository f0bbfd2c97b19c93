"""Why SESAME does not beat plain SAD on the corridor: a masking ablation on the real outside data.

Single-image matching of the 111 corridor queries against the 111 references (``../shared/data/corridor``),
64x48 patch-normalised thumbnails, no shift search (the ``route`` preset; on the corridor the +-4/+-2 search
changes no match). Every run uses the project's own masks (``core.sesame.masks.sesame_masks``) and the project's
SAD (``core.place_recognition.single.distance_matrix``, which applies the query's mask as eq. 6); the ablation rows that need a
mask the implementation does not offer (both images' masks, random masks, the inverted mask) use the same
mean absolute difference over the weighted pixels, computed here with numpy. Prints recall@1, AUC and the
fraction of pixels each mask keeps:

* the paper's variants: r_threshold 0.1-0.7; hierarchy as section 4.4's words (union of salient masks) and
  as eq. 10 read literally (intersection of salient masks); 256 or 32 histogram bins; mask at R_x = 160 or at
  the 64-pixel thumbnail; the query's mask (eq. 6) or both images' masks (eq. 2);
* the paper's comparison size (Table 1: 160 px wide, patch normalisation over 5 px);
* controls that show where the corridor's place information is: a random block mask keeping the same
  fraction of pixels, and the inverted mask (only the plain patches).

Skips cleanly (exit 0) when the data folder is absent. Usage:
``.venv/bin/python bench/sesame_corridor.py [--data ../shared/data]``
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.place_recognition import metrics
from driftmap.core.place_recognition.single import (
    VPR_ROUTE,
    VprParams,
    distance_matrix,
    match_single,
    prepare_images,
    thumbnail_params,
)
from driftmap.core.sesame import masks as saliency
from driftmap.formats.place_images import gt_matrix, list_images, read_gray_stack, read_gt_pairs

ROOT = Path(__file__).resolve().parents[1]
F32 = NDArray[np.float32]
BoolArr = NDArray[np.bool_]


def masks(images: NDArray[np.uint8], params: VprParams, sesame: saliency.SesameParams) -> BoolArr:
    """SESAME masks on the thumbnails, computed at ``params.mask_width_px`` wide."""
    h, w = images.shape[1:]
    mw = min(params.mask_width_px, w)
    size = (mw, max(2, round(mw * h / w)))
    return saliency.sesame_masks(images, replace(sesame, mask_size_px=size), thumbnail_params((h, w), params))


def weighted_distances(tq: F32, td: F32, wq: BoolArr | None, wd: BoolArr | None) -> F32:
    """``(Q, D)`` mean absolute difference over pixels weighted by the query's and the reference's masks."""
    a = np.ones(tq.shape, np.float32) if wq is None else wq.astype(np.float32)
    b = np.ones(td.shape, np.float32) if wd is None else wd.astype(np.float32)
    out = np.empty((tq.shape[0], td.shape[0]), dtype=np.float32)
    for i in range(tq.shape[0]):
        weight = a[i][None] * b
        num = (np.abs(tq[i][None] - td) * weight).sum(axis=(1, 2))
        den = weight.sum(axis=(1, 2))
        out[i] = np.where(den > 0, num / np.maximum(den, 1e-9), np.inf)
    return out


def score(d: F32, gt: BoolArr) -> tuple[float, float]:
    m = match_single(d)
    result, _ = metrics.evaluate_matches(m.db_index, m.score, gt)
    return result.recall_at_1, result.auc


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    folder = parser.parse_args().data / "corridor"
    if not (folder / "gt.csv").is_file():
        print(f"skipped: no corridor data under {folder.parent}")
        return
    db_files, q_files = list_images(folder / "db"), list_images(folder / "query")
    gt = gt_matrix(read_gt_pairs(folder / "gt.csv", q_files, db_files), q_files, db_files)
    query, db = read_gray_stack(q_files), read_gray_stack(db_files)
    pq, pd = prepare_images(query, "sad", VPR_ROUTE), prepare_images(db, "sad", VPR_ROUTE)
    r1, auc = score(distance_matrix(pq, pd, VPR_ROUTE), gt)
    print(f"{'run':<58} {'recall@1':>8} {'AUC':>6} {'kept':>5}")
    print(f"{'plain SAD (baseline)':<58} {r1:8.3f} {auc:6.3f} {1.0:5.2f}")
    r1, auc = score(
        distance_matrix(*(prepare_images(x, "sesame", VPR_ROUTE) for x in (query, db)), VPR_ROUTE), gt
    )
    kept = float(masks(query, VPR_ROUTE, saliency.SESAME_DEFAULT).mean())
    print(
        f"{'SESAME as shipped (DEFAULT, core.place_recognition.single)':<58} {r1:8.3f} {auc:6.3f} {kept:5.2f}"
    )
    paper_size = replace(VPR_ROUTE, thumb_width_px=160, patch_px=5)  # Table 1: R_x 160, L_norm 5
    for method in ("sad", "sesame"):
        prep = [prepare_images(x, method, paper_size) for x in (query, db)]
        r1, auc = score(distance_matrix(*prep, paper_size), gt)
        kept = 1.0 if prep[0].masks is None else float(prep[0].masks.mean())
        print(
            f"{method.upper() + ' at the paper size (160x120, L_norm 5)':<58} {r1:8.3f} {auc:6.3f} {kept:5.2f}"
        )
    rng = np.random.default_rng(0)
    for mask_w in (160, 64):
        params = replace(VPR_ROUTE, mask_width_px=mask_w)
        for bins in (256, 32):
            for hierarchy in ("union", "intersection"):
                for r in (0.1, 0.3, 0.5, 0.7):
                    ses = replace(saliency.SESAME_DEFAULT, bins=bins, r_threshold=r)
                    if hierarchy == "union":
                        mq, md = masks(query, params, ses), masks(db, params, ses)
                    else:  # eq. 10 read literally: salient at every scale
                        per = [
                            masks(x, params, replace(ses, patch_sizes_px=(s,)))
                            for s in (5, 10, 20)
                            for x in (query, db)
                        ]
                        mq = per[0] & per[2] & per[4]
                        md = per[1] & per[3] & per[5]
                    name = f"mask {mask_w} px, {bins} bins, {hierarchy}, r {r}"
                    for side, wd in (("query", None), ("both", md)):
                        r1, auc = score(weighted_distances(pq.thumbs, pd.thumbs, mq, wd), gt)
                        print(f"{name + ', ' + side:<58} {r1:8.3f} {auc:6.3f} {mq.mean():5.2f}")
                    if mask_w == 160 and r == 0.5 and (bins == 256 or hierarchy == "intersection"):
                        r1, auc = score(weighted_distances(pq.thumbs, pd.thumbs, ~mq, None), gt)
                        print(
                            f"{'  control: inverted mask (plain patches only)':<58} {r1:8.3f} {auc:6.3f} {1 - mq.mean():5.2f}"
                        )
                        rs = []
                        for _ in range(5):
                            blocks = (rng.random((mq.shape[0], 24, 32)) < mq.mean()).astype(np.uint8)
                            hw = mq.shape[2], mq.shape[1]
                            rand = (
                                np.stack([cv2.resize(b, hw, interpolation=cv2.INTER_NEAREST) for b in blocks])
                                > 0
                            )
                            rs.append(score(weighted_distances(pq.thumbs, pd.thumbs, rand, None), gt))
                        r1, auc = np.mean(rs, axis=0)
                        print(
                            f"{'  control: random 2x2-px blocks, same fraction (5 draws)':<58} {r1:8.3f} {auc:6.3f} {mq.mean():5.2f}"
                        )


if __name__ == "__main__":
    main()

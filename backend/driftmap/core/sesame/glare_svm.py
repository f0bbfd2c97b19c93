"""Linear SVM image-quality classifier that removes glare-struck frames from the database ([SESAME], 3.5).

Frames lit by a lamp or a head-light change intensity gradually, so their patch entropy is not low enough
for SESAME to drop them, yet the bright blob attracts false matches. The paper trains a linear SVM on
artificial data made from a few hand-picked frames of typical tunnel scenes:

* "bad" images: a source frame with Gaussian blobs of random position, size and intensity added, the
  saturation of bright light shining into the camera (:func:`make_glare`);
* "good" images: random-sized rectangles stitched together from randomly chosen source frames, each taken
  from near its own location in the source (:func:`make_stitched`).

The paper does not say what the SVM sees. Here it sees a cheap, position-independent summary of the frame
at ``feature_size_px`` (:func:`quality_features`): the intensity histogram, the clipped-white and
clipped-black fractions, a histogram of 10-px patch entropies (eq. 5), a histogram of Sobel gradient
magnitudes, and the sorted means and standard deviations of a grid of blocks. Features are standardised and
a :class:`sklearn.svm.LinearSVC` is fitted; everything is seeded, so a seed gives the same classifier.
Synthetic images are made at ``feature_size_px`` (the source frames are reduced first), which is all the
features look at and keeps training to a fraction of a second.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import cv2
import numpy as np
from numpy.typing import NDArray
from sklearn.svm import LinearSVC

from driftmap.core.imaging.images import downsample
from driftmap.core.sesame.masks import patch_entropy
from driftmap.core.types import F64, U8
from driftmap.errors import BadInputError

__all__ = [
    "QUALITY_DEFAULT",
    "QUALITY_FAST",
    "QualityClassifier",
    "QualityParams",
    "make_glare",
    "make_stitched",
    "quality_features",
    "train_quality_classifier",
]


@dataclass(frozen=True)
class QualityParams:
    """Synthetic training data and the linear SVM of the image-quality classifier ([SESAME], 3.5, 4.3)."""

    feature_size_px: tuple[int, int] = (160, 76)  # (width, height) frames are reduced to before features
    n_train_per_class: int = 200  # synthetic "good" and "bad" images each for training
    n_holdout_per_class: int = 50  # fresh synthetic images each for the held-out accuracy
    blobs: tuple[int, int] = (1, 3)  # fewest and most glare blobs per "bad" image
    blob_sigma: tuple[float, float] = (0.15, 0.6)  # blob standard deviation, fraction of the image height
    blob_gain: tuple[float, float] = (0.8, 2.0)  # blob peak added to the frame, x 255 grey levels (clipped)
    stitch_patch: tuple[float, float] = (0.15, 0.5)  # stitched rectangle side, fraction of the image side
    stitch_jitter: float = 0.05  # rectangles come from within this fraction of the side of their location
    grid: tuple[int, int] = (8, 4)  # (cols, rows) blocks whose sorted means and stds are features
    c: float = 1.0  # SVM regularisation C (larger fits the training data harder)

    def __post_init__(self) -> None:
        if min(self.feature_size_px) < 20:
            raise BadInputError(f"must be >= 20 px, got {self.feature_size_px}", field="feature_size_px")
        if self.n_train_per_class < 2 or self.n_holdout_per_class < 0:
            raise BadInputError("need >= 2 training images per class", field="n_train_per_class")
        for name in ("blobs", "blob_sigma", "blob_gain", "stitch_patch"):
            lo, hi = getattr(self, name)
            if not 0 < lo <= hi:
                raise BadInputError(f"must be 0 < low <= high, got {(lo, hi)}", field=name)
        if not 0 <= self.stitch_jitter < 1 or self.c <= 0 or min(self.grid) < 1:
            raise BadInputError("stitch_jitter in [0, 1), c > 0, grid >= (1, 1)", field="stitch_jitter")


QUALITY_DEFAULT = QualityParams()
QUALITY_FAST = QualityParams(n_train_per_class=80, n_holdout_per_class=20)

_HIST_BINS = 16
_ENTROPY_PATCH_PX = 10
_ENTROPY_BINS = 8
_GRAD_EDGES = np.r_[0.0, np.geomspace(2.0, 256.0, 8)[:-1], np.inf]  # Sobel magnitude, grey levels / px


def _stack(frames: NDArray[np.generic], name: str) -> U8:
    arr = np.asarray(frames)
    if arr.ndim == 2:
        arr = arr[None]
    if arr.dtype != np.uint8 or arr.ndim != 3 or 0 in arr.shape:
        raise BadInputError(f"must be uint8 (N, H, W) or (H, W), got {arr.dtype} {arr.shape}", field=name)
    return arr


def make_glare(frames: U8, rng: np.random.Generator, params: QualityParams = QUALITY_DEFAULT) -> U8:
    """ "Bad" images: each frame with Gaussian glare blobs of random count, position, size and intensity.

    Args:
        frames: ``(N, H, W)`` uint8 gray frames.
        rng: random generator (consumed).
        params: ``blobs``, ``blob_sigma`` (fraction of H) and ``blob_gain`` (x 255 grey levels).

    Returns:
        ``(N, H, W)`` uint8: ``clip(frame + 255 sum_b g_b exp(-|p - c_b|^2 / (2 s_b^2)), 0, 255)``.
    """
    stack = _stack(frames, "frames")
    n, h, w = stack.shape
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    out = np.empty_like(stack)
    for i in range(n):
        light = np.zeros((h, w))
        for _ in range(int(rng.integers(params.blobs[0], params.blobs[1] + 1))):
            cx, cy = rng.uniform(0, w), rng.uniform(0, h)
            sigma = rng.uniform(*params.blob_sigma) * h
            light += rng.uniform(*params.blob_gain) * np.exp(
                -((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * sigma**2)
            )
        out[i] = np.clip(stack[i] + 255.0 * light, 0, 255).astype(np.uint8)
    return out


def _cuts(length: int, frac: tuple[float, float], rng: np.random.Generator) -> list[int]:
    cuts = [0]
    while cuts[-1] < length:
        cuts.append(min(length, cuts[-1] + max(2, round(rng.uniform(*frac) * length))))
    return cuts


def make_stitched(
    sources: U8, n: int, rng: np.random.Generator, params: QualityParams = QUALITY_DEFAULT
) -> U8:
    """ "Good" images: random-sized rectangles stitched from random source frames, each near its location.

    Args:
        sources: ``(S, H, W)`` uint8 gray frames of typical, clean scenes.
        n: number of images to make.
        rng: random generator (consumed).
        params: ``stitch_patch`` (rectangle side, fraction of the side) and ``stitch_jitter``.

    Returns:
        ``(n, H, W)`` uint8.
    """
    src = _stack(sources, "sources")
    s, h, w = src.shape
    out = np.empty((n, h, w), dtype=np.uint8)
    jy, jx = round(params.stitch_jitter * h), round(params.stitch_jitter * w)
    for i in range(n):
        ys, xs = _cuts(h, params.stitch_patch, rng), _cuts(w, params.stitch_patch, rng)
        for y0, y1 in pairwise(ys):
            for x0, x1 in pairwise(xs):
                dy = int(np.clip(rng.integers(-jy, jy + 1), -y0, h - y1))
                dx = int(np.clip(rng.integers(-jx, jx + 1), -x0, w - x1))
                out[i, y0:y1, x0:x1] = src[int(rng.integers(s)), y0 + dy : y1 + dy, x0 + dx : x1 + dx]
    return out


def quality_features(frames: NDArray[np.generic], params: QualityParams = QUALITY_DEFAULT) -> F64:
    """Position-independent summary of each frame that the SVM classifies.

    Args:
        frames: ``(N, H, W)`` or ``(H, W)`` uint8 gray frames (any size; reduced to ``feature_size_px``).
        params: ``feature_size_px`` and ``grid``.

    Returns:
        float64 ``(N, D)``: intensity histogram (16, fractions), white/black-clipped fractions (2), 10-px patch
        entropy histogram (8, fractions of ``[0, log2 100]`` bits), Sobel magnitude histogram (8, fractions),
        sorted block means and sorted block standard deviations (``2 cols rows``, / 255).
    """
    small = downsample(np.ascontiguousarray(_stack(frames, "frames")), params.feature_size_px)
    n = small.shape[0]
    flat = small.reshape(n, -1)
    px = flat.shape[1]
    inten = np.stack([np.bincount(f >> 4, minlength=_HIST_BINS) for f in flat]) / px
    clipped = np.stack([(flat >= 250).mean(axis=1), (flat <= 5).mean(axis=1)], axis=1)
    ent = patch_entropy(small, _ENTROPY_PATCH_PX).reshape(n, -1)
    e_max = np.log2(_ENTROPY_PATCH_PX**2)
    ent_hist = np.stack([np.histogram(e, _ENTROPY_BINS, (0.0, e_max + 1e-9))[0] for e in ent]) / ent.shape[1]
    grads = []
    for im in small.astype(np.float32):
        mag = cv2.magnitude(cv2.Sobel(im, cv2.CV_32F, 1, 0), cv2.Sobel(im, cv2.CV_32F, 0, 1))
        grads.append(np.histogram(mag, _GRAD_EDGES)[0] / px)
    gx, gy = params.grid
    h, w = small.shape[1:]
    blocks = small[:, : h - h % gy, : w - w % gx].reshape(n, gy, h // gy, gx, w // gx).astype(np.float64)
    means = np.sort(blocks.mean(axis=(2, 4)).reshape(n, -1), axis=1) / 255.0
    stds = np.sort(blocks.std(axis=(2, 4)).reshape(n, -1), axis=1) / 255.0
    return np.concatenate([inten, clipped, ent_hist, np.stack(grads), means, stds], axis=1)


@dataclass(frozen=True, eq=False)
class QualityClassifier:
    """A trained linear image-quality classifier: ``good <=> w . (f - mean) / scale + b > 0``.

    Attributes:
        coef: ``(D,)`` float64 SVM weights on standardised features.
        intercept: SVM bias.
        feature_mean: ``(D,)`` float64 training mean of each feature.
        feature_scale: ``(D,)`` float64 training standard deviation of each feature (1 where constant).
        holdout_accuracy: accuracy on fresh synthetic images of both classes (nan when none were made).
        params: the parameters the features were computed with.
    """

    coef: F64
    intercept: float
    feature_mean: F64
    feature_scale: F64
    holdout_accuracy: float
    params: QualityParams = QUALITY_DEFAULT

    def score(self, frames: NDArray[np.generic]) -> F64:
        """Signed SVM decision value per frame, ``(N,)`` float64; > 0 means good, larger is better."""
        z = (quality_features(frames, self.params) - self.feature_mean) / self.feature_scale
        return np.asarray(z @ self.coef + self.intercept, dtype=np.float64)

    def predict(self, frames: NDArray[np.generic]) -> NDArray[np.bool_]:
        """``(N,)`` bool: True for frames fit for the database (no glare), for ``(N, H, W)`` uint8 input."""
        return np.asarray(self.score(frames) > 0)

    def to_arrays(self) -> dict[str, NDArray[np.generic]]:
        """Plain arrays for the store; :meth:`from_arrays` restores the classifier."""
        return {
            "coef": self.coef,
            "intercept": np.array([self.intercept]),
            "feature_mean": self.feature_mean,
            "feature_scale": self.feature_scale,
            "holdout_accuracy": np.array([self.holdout_accuracy]),
            "feature_size_px": np.array(self.params.feature_size_px, dtype=np.int64),
            "grid": np.array(self.params.grid, dtype=np.int64),
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, NDArray[np.generic]]) -> QualityClassifier:
        """Rebuild from :meth:`to_arrays` output; raises :class:`BadInputError` on missing or bad arrays."""
        try:
            coef = np.asarray(arrays["coef"], dtype=np.float64)
            mean = np.asarray(arrays["feature_mean"], dtype=np.float64)
            scale = np.asarray(arrays["feature_scale"], dtype=np.float64)
            size = tuple(int(v) for v in arrays["feature_size_px"])
            grid = tuple(int(v) for v in arrays["grid"])
            intercept = float(np.asarray(arrays["intercept"]).ravel()[0])
            acc = float(np.asarray(arrays["holdout_accuracy"]).ravel()[0])
        except KeyError as err:
            raise BadInputError(f"missing array {err}", field="quality") from err
        if coef.ndim != 1 or mean.shape != coef.shape or scale.shape != coef.shape or len(size) != 2:
            raise BadInputError("coef, feature_mean and feature_scale must be (D,)", field="quality")
        params = QualityParams(feature_size_px=(size[0], size[1]), grid=(grid[0], grid[1]))
        return cls(coef, intercept, mean, scale, acc, params)


def _dataset(
    sources: U8, n: int, rng: np.random.Generator, params: QualityParams
) -> tuple[F64, NDArray[np.int64]]:
    good = make_stitched(sources, n, rng, params)
    bad = make_glare(sources[rng.integers(sources.shape[0], size=n)], rng, params)
    x = quality_features(np.concatenate([good, bad]), params)
    return x, np.r_[np.ones(n, dtype=np.int64), np.zeros(n, dtype=np.int64)]


def train_quality_classifier(
    source_frames: NDArray[np.generic], seed: int, params: QualityParams = QUALITY_DEFAULT
) -> QualityClassifier:
    """Train the glare classifier on synthetic images made from a few clean frames of typical scenes.

    Args:
        source_frames: ``(N, H, W)`` uint8 gray frames of clean, typical scenes (the paper uses 20).
        seed: seeds data generation and the SVM; the same seed and frames give the same classifier.
        params: synthetic data and SVM parameters.

    Returns:
        :class:`QualityClassifier` with its held-out accuracy on fresh synthetic images.
    """
    sources = downsample(np.ascontiguousarray(_stack(source_frames, "source_frames")), params.feature_size_px)
    rng = np.random.default_rng(seed)
    x, y = _dataset(sources, params.n_train_per_class, rng, params)
    mean = x.mean(axis=0)
    scale = x.std(axis=0)
    scale[scale < 1e-12] = 1.0
    svm = LinearSVC(C=params.c, random_state=seed, max_iter=20000)
    svm.fit((x - mean) / scale, y)
    clf = QualityClassifier(
        coef=np.asarray(svm.coef_[0], dtype=np.float64),
        intercept=float(svm.intercept_[0]),
        feature_mean=mean,
        feature_scale=scale,
        holdout_accuracy=float("nan"),
        params=params,
    )
    if params.n_holdout_per_class == 0:
        return clf
    xh, yh = _dataset(sources, params.n_holdout_per_class, rng, params)
    acc = float(np.mean(((xh - mean) / scale @ clf.coef + clf.intercept > 0) == (yh == 1)))
    return QualityClassifier(clf.coef, clf.intercept, mean, scale, acc, params)

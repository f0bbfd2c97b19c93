"""Tests of the glare image-quality classifier ([SESAME], section 3.5)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from driftmap.core.sesame.glare_svm import (
    QUALITY_FAST,
    QualityClassifier,
    QualityParams,
    make_glare,
    make_stitched,
    quality_features,
    train_quality_classifier,
)
from driftmap.errors import BadInputError

TRAIN_SEED = 3
SOURCE_SEED = 1
TEST_SEED = 2
GLARE_SEED = 4
MIN_ACCURACY = 0.9  # held-out glare vs clean textured frames
N_SOURCES = 20  # the paper hand-picks 20 source frames
N_TEST = 40


def textured_frames(rng: np.random.Generator, n: int, h: int = 96, w: int = 200) -> np.ndarray:
    """Synthetic tunnel-like frames: multi-scale smooth noise, a brightness ramp and a few rectangles."""
    out = []
    for _ in range(n):
        img = np.full((h, w), rng.uniform(40, 140)) + np.linspace(-20, 20, h)[:, None] * rng.uniform(-1, 1)
        for s in (2, 6, 15):
            noise = rng.normal(0, 1, (h // s + 1, w // s + 1))
            img += cv2.resize(noise, (w, h), interpolation=cv2.INTER_CUBIC) * rng.uniform(5, 20)
        for _ in range(int(rng.integers(2, 6))):
            x0, y0 = int(rng.integers(0, w - 20)), int(rng.integers(0, h - 10))
            img[y0 : y0 + int(rng.integers(5, 30)), x0 : x0 + int(rng.integers(10, 60))] += rng.uniform(
                -60, 60
            )
        out.append(np.clip(img, 0, 255).astype(np.uint8))
    return np.stack(out)


@pytest.fixture(scope="module")
def sources() -> np.ndarray:
    return textured_frames(np.random.default_rng(SOURCE_SEED), N_SOURCES)


@pytest.fixture(scope="module")
def classifier(sources: np.ndarray) -> QualityClassifier:
    return train_quality_classifier(sources, TRAIN_SEED, QUALITY_FAST)


class TestSyntheticData:
    def test_glare_brightens_and_saturates(self, sources: np.ndarray) -> None:
        bad = make_glare(sources[:5], np.random.default_rng(GLARE_SEED))
        assert bad.shape == (5, *sources.shape[1:]) and bad.dtype == np.uint8
        assert np.all(bad >= sources[:5])  # light only adds
        assert np.all((bad == 255).reshape(5, -1).any(axis=1))  # every blob peak of gain >= 0.8 saturates

    def test_stitched_pixels_come_from_sources_nearby(self, sources: np.ndarray) -> None:
        good = make_stitched(sources, 3, np.random.default_rng(GLARE_SEED))
        assert good.shape == (3, *sources.shape[1:]) and good.dtype == np.uint8
        vals = set(np.unique(sources).tolist())
        assert set(np.unique(good).tolist()) <= vals
        assert not np.array_equal(good[0], good[1])

    def test_features_shape_and_finite(self, sources: np.ndarray) -> None:
        f = quality_features(sources)
        assert f.shape[0] == N_SOURCES and f.ndim == 2
        assert np.all(np.isfinite(f))
        assert np.allclose(f[:, :16].sum(axis=1), 1.0)  # the intensity histogram sums to 1


class TestClassifier:
    def test_separates_held_out_glare_from_clean(self, classifier: QualityClassifier) -> None:
        clean = textured_frames(np.random.default_rng(TEST_SEED), N_TEST)
        glare = make_glare(clean, np.random.default_rng(GLARE_SEED))
        good_clean = classifier.predict(clean)
        good_glare = classifier.predict(glare)
        accuracy = (good_clean.sum() + (~good_glare).sum()) / (2 * N_TEST)
        assert accuracy >= MIN_ACCURACY
        assert classifier.holdout_accuracy >= MIN_ACCURACY
        assert classifier.score(clean).mean() > classifier.score(glare).mean()

    def test_single_frame_input(self, classifier: QualityClassifier, sources: np.ndarray) -> None:
        assert classifier.predict(sources[0]).shape == (1,)
        assert classifier.score(sources[0]).dtype == np.float64

    def test_deterministic_per_seed(self, sources: np.ndarray, classifier: QualityClassifier) -> None:
        again = train_quality_classifier(sources, TRAIN_SEED, QUALITY_FAST)
        assert np.array_equal(again.coef, classifier.coef)
        assert again.intercept == classifier.intercept
        frames = textured_frames(np.random.default_rng(TEST_SEED), 5)
        assert np.array_equal(again.score(frames), classifier.score(frames))

    def test_arrays_round_trip(self, classifier: QualityClassifier, sources: np.ndarray) -> None:
        arrays = classifier.to_arrays()
        assert all(isinstance(v, np.ndarray) for v in arrays.values())
        back = QualityClassifier.from_arrays(arrays)
        assert np.array_equal(back.score(sources), classifier.score(sources))
        assert back.params.feature_size_px == classifier.params.feature_size_px
        assert math.isclose(back.holdout_accuracy, classifier.holdout_accuracy)

    def test_from_arrays_rejects_missing(self, classifier: QualityClassifier) -> None:
        arrays = classifier.to_arrays()
        del arrays["coef"]
        with pytest.raises(BadInputError):
            QualityClassifier.from_arrays(arrays)


class TestParams:
    def test_rejects_bad_ranges(self) -> None:
        with pytest.raises(BadInputError):
            QualityParams(blob_sigma=(0.5, 0.1))
        with pytest.raises(BadInputError):
            QualityParams(feature_size_px=(10, 10))

    def test_rejects_non_uint8(self) -> None:
        with pytest.raises(BadInputError):
            quality_features(np.zeros((2, 40, 40), dtype=np.float32))

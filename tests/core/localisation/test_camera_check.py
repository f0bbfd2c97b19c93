"""The obscured-camera judgement on the simulator's frames: clean vs its dust and water copies ([SSLAM] IV-A)."""

from __future__ import annotations

import csv
from pathlib import Path

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.core.localisation.camera_check import (
    OBSCURED_DEFAULT,
    ObscuredJudgement,
    ObscuredState,
    frame_measures,
    judge_obscured,
)
from driftmap.errors import BadInputError
from driftmap.sim.obscurants import LEVELS, apply_level, water_centre, water_diameter_px

FRAMES = 60  # six seconds of a localisation drive at 10 frames/s


@pytest.fixture(scope="module")
def clean(tiny_site_dir: Path) -> tuple[list[float], list[NDArray[np.uint8]]]:
    """The first frames of the tiny site's localisation drive: times (s) and grey images."""
    drive = sorted(p for p in (tiny_site_dir / "drives").iterdir() if p.name.startswith("loc"))[0]
    with (drive / "frames.csv").open() as handle:
        rows = list(csv.DictReader(handle))[:FRAMES]
    images = [
        cv2.imread(str(drive / "frames" / f"{int(r['frame']):06d}.png"), cv2.IMREAD_GRAYSCALE) for r in rows
    ]
    return [float(r["t"]) for r in rows], images


def _judge(times: list[float], images: list[NDArray[np.uint8]]) -> list[ObscuredJudgement]:
    state, out = ObscuredState(), []
    for t, image in zip(times, images, strict=True):
        state, judgement = judge_obscured(state, frame_measures(image), t)
        out.append(judgement)
    return out


def _obscured_copy(images: list[NDArray[np.uint8]], level: str, seed: int) -> list[NDArray[np.uint8]]:
    rng = np.random.default_rng(seed)
    spec = LEVELS[level]
    centre = (
        water_centre(
            images[0].shape, water_diameter_px(spec.water_diameter_paper_px, images[0].shape[1]), rng
        )
        if spec.kind == "water"
        else None
    )
    return [apply_level(image, spec, rng, centre) for image in images]


class TestObscured:
    def test_clean_frames_are_never_judged_obscured(
        self, clean: tuple[list[float], list[NDArray[np.uint8]]]
    ) -> None:
        judgements = _judge(*clean)
        assert not any(j.obscured for j in judgements)
        assert max(j.speckle for j in judgements) < OBSCURED_DEFAULT.speckle_max / 10
        assert max(j.flat_area for j in judgements) == 0.0
        assert min(j.salient for j in judgements) > 0.8

    @pytest.mark.parametrize(
        ("level", "reason"), [("dust1", "dust"), ("dust2", "dust"), ("water1", "water"), ("water2", "water")]
    )
    def test_dust_and_water_copies_are_judged_obscured_after_the_warm_up(
        self, clean: tuple[list[float], list[NDArray[np.uint8]]], level: str, reason: str
    ) -> None:
        times, images = clean
        for seed in (1, 2):
            judgements = _judge(times, _obscured_copy(images, level, seed))
            warm = OBSCURED_DEFAULT.warmup_frames
            assert not any(j.obscured for j in judgements[: warm - 1])
            assert all(j.obscured and j.reason == reason for j in judgements[warm - 1 :]), (level, seed)

    def test_a_covered_lens_is_judged_covered(
        self, clean: tuple[list[float], list[NDArray[np.uint8]]]
    ) -> None:
        times, images = clean
        rng = np.random.default_rng(3)
        covered = [
            np.clip(40 + 0.05 * image + rng.normal(0, 1.5, image.shape), 0, 255).astype(np.uint8)
            for image in images
        ]
        judgements = _judge(times, covered)
        assert judgements[-1].obscured and judgements[-1].reason == "covered"

    def test_the_judgement_clears_when_the_lens_is_wiped(
        self, clean: tuple[list[float], list[NDArray[np.uint8]]]
    ) -> None:
        times, images = clean
        half = len(images) // 2
        judgements = _judge(times, _obscured_copy(images[:half], "dust2", 4) + images[half:])
        assert judgements[half - 1].obscured
        assert not judgements[
            -1
        ].obscured  # three seconds of clean frames wash the smoothed speckle out (smooth_s = 1 s)

    def test_state_round_trips_through_arrays(
        self, clean: tuple[list[float], list[NDArray[np.uint8]]]
    ) -> None:
        times, images = clean
        state = ObscuredState()
        for t, image in zip(times[:5], images[:5], strict=True):
            state, _ = judge_obscured(state, frame_measures(image), t)
        again = ObscuredState.from_arrays(state.to_arrays())
        assert again.t_s == state.t_s and again.frames == 5 and again.speckle == state.speckle
        assert again.memory is not None and state.memory is not None
        np.testing.assert_array_equal(again.memory, state.memory)
        assert ObscuredState.from_arrays(ObscuredState().to_arrays()) == ObscuredState()

    def test_time_going_back_restarts_the_memory(
        self, clean: tuple[list[float], list[NDArray[np.uint8]]]
    ) -> None:
        times, images = clean
        state, _ = judge_obscured(ObscuredState(), frame_measures(images[0]), times[1])
        state, _ = judge_obscured(state, frame_measures(images[1]), times[0])
        assert state.frames == 1

    def test_bad_frames_are_refused(self) -> None:
        with pytest.raises(BadInputError):
            frame_measures(np.zeros((10, 10), np.uint8))
        with pytest.raises(BadInputError):
            frame_measures(np.zeros((64, 64), np.float32))  # type: ignore[arg-type]

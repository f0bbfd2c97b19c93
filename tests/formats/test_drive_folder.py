"""Tests of driftmap.formats.drive_folder: writing, reading, validating and image checking."""

from __future__ import annotations

from pathlib import Path

import pytest

from driftmap.errors import BadInputError, ConflictError
from driftmap.formats.drive_folder import iter_frame_images, read_drive_folder, write_drive_folder
from driftmap.formats.records import FrameRow, GroundingRow
from tests.formats.builders import make_frames, make_groundings, make_jpeg, make_meta, make_png


def write_sample(out: Path, *, n: int = 5, truth: bool = True, homography: bool = False) -> None:
    frames = make_frames(n, truth=truth)
    write_drive_folder(
        out, make_meta(homography=homography), frames, (make_png(i) for i in range(n)), make_groundings()
    )


class TestWriteThenRead:
    @pytest.mark.parametrize("homography", [False, True])
    @pytest.mark.parametrize("truth", [False, True])
    def test_round_trip_gives_equal_records(self, tmp_path: Path, truth: bool, homography: bool) -> None:
        out = tmp_path / "drive"
        frames = make_frames(6, truth=truth)
        images = [make_png(i) for i in range(6)]
        write_drive_folder(out, make_meta(homography=homography), frames, iter(images), make_groundings())
        folder = read_drive_folder(out)
        assert folder.meta == make_meta(homography=homography)
        assert folder.frames == frames
        assert folder.groundings == make_groundings()
        assert [p.name for p in folder.frame_files] == [f"{i:06d}.png" for i in range(6)]
        assert [data for _, data in iter_frame_images(folder)] == images

    def test_rewrite_is_byte_identical(self, tmp_path: Path) -> None:
        write_sample(tmp_path / "a", homography=True)
        first = read_drive_folder(tmp_path / "a")
        write_drive_folder(
            tmp_path / "b",
            first.meta,
            first.frames,
            (data for _, data in iter_frame_images(first)),
            first.groundings,
        )
        for name in ("drive.json", "frames.csv", "groundings.csv", "frames/000004.png"):
            assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name

    def test_absent_truth_is_written_as_empty_cells(self, tmp_path: Path) -> None:
        write_drive_folder(
            tmp_path / "d", make_meta(), make_frames(2, truth=False), [make_png(0), make_png(1)]
        )
        assert (tmp_path / "d" / "frames.csv").read_text() == "frame,t,x,y,yaw\n0,0.0,,,\n1,0.1,,,\n"

    def test_no_groundings_file_unless_given(self, tmp_path: Path) -> None:
        write_drive_folder(tmp_path / "d", make_meta(), make_frames(2), [make_png(0), make_png(1)])
        assert not (tmp_path / "d" / "groundings.csv").exists()
        assert read_drive_folder(tmp_path / "d").groundings == []

    def test_jpeg_frames_are_named_by_extension(self, tmp_path: Path) -> None:
        write_drive_folder(
            tmp_path / "d", make_meta(), make_frames(2), [make_jpeg(0), make_jpeg(1)], image_ext=".jpg"
        )
        folder = read_drive_folder(tmp_path / "d")
        assert [p.name for p in folder.frame_files] == ["000000.jpg", "000001.jpg"]
        assert len(list(iter_frame_images(folder))) == 2

    def test_sparse_frame_numbers_name_the_files(self, tmp_path: Path) -> None:
        frames = [FrameRow(7, 0.0), FrameRow(1234567, 0.5)]
        write_drive_folder(tmp_path / "d", make_meta(), frames, [make_png(0), make_png(1)])
        assert sorted(p.name for p in (tmp_path / "d" / "frames").iterdir()) == ["000007.png", "1234567.png"]


class TestWriteAtomically:
    def test_refuses_to_overwrite_a_non_empty_folder(self, tmp_path: Path) -> None:
        write_sample(tmp_path / "d")
        with pytest.raises(ConflictError, match="not empty"):
            write_sample(tmp_path / "d")

    def test_overwrite_flag_replaces_the_folder(self, tmp_path: Path) -> None:
        write_sample(tmp_path / "d", n=5)
        write_drive_folder(
            tmp_path / "d", make_meta(), make_frames(2), [make_png(0), make_png(1)], overwrite=True
        )
        assert len(read_drive_folder(tmp_path / "d").frames) == 2
        assert len(list((tmp_path / "d" / "frames").iterdir())) == 2
        assert [p.name for p in tmp_path.iterdir()] == ["d"]

    def test_an_existing_empty_folder_is_used(self, tmp_path: Path) -> None:
        (tmp_path / "d").mkdir()
        write_sample(tmp_path / "d")
        assert read_drive_folder(tmp_path / "d").meta == make_meta()

    @pytest.mark.parametrize("count", [3, 7])
    def test_wrong_number_of_images_leaves_nothing_behind(self, tmp_path: Path, count: int) -> None:
        with pytest.raises(BadInputError, match="images"):
            write_drive_folder(
                tmp_path / "d", make_meta(), make_frames(5), (make_png(i) for i in range(count))
            )
        assert list(tmp_path.iterdir()) == []

    def test_failing_image_source_leaves_nothing_behind(self, tmp_path: Path) -> None:
        def images() -> object:
            yield make_png(0)
            raise RuntimeError("camera unplugged")

        with pytest.raises(RuntimeError):
            write_drive_folder(tmp_path / "d", make_meta(), make_frames(3), images())  # type: ignore[arg-type]
        assert list(tmp_path.iterdir()) == []

    @pytest.mark.parametrize(
        ("frames", "field"),
        [
            ([FrameRow(0, 0.0), FrameRow(0, 1.0)], "frame"),
            ([FrameRow(0, 1.0), FrameRow(1, 1.0)], "t"),
            ([FrameRow(0, 0.0, 1.0, None, 0.0)], "y"),
            ([], "frame"),
        ],
    )
    def test_rows_a_reader_would_reject_are_refused(
        self, tmp_path: Path, frames: list[FrameRow], field: str
    ) -> None:
        with pytest.raises(BadInputError) as info:
            write_drive_folder(tmp_path / "d", make_meta(), frames, [make_png(0)] * len(frames))
        assert info.value.field == field
        assert list(tmp_path.iterdir()) == []

    def test_groundings_of_absent_frames_are_refused(self, tmp_path: Path) -> None:
        with pytest.raises(BadInputError, match=r"not in frames\.csv"):
            write_drive_folder(
                tmp_path / "d", make_meta(), make_frames(2), [make_png(0)] * 2, [GroundingRow(9, 0.0, 0.0)]
            )

"""Tests of driftmap.formats.drive_folder: writing, reading, validating and image checking."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from driftmap.errors import BadInputError, ConflictError
from driftmap.formats.bounds import MAX_ABS_T_S
from driftmap.formats.drive_folder import (
    frames_text,
    iter_frame_images,
    parse_frames_csv,
    read_drive_folder,
    write_drive_folder,
)
from driftmap.formats.records import DriveMeta, FrameRow, GroundingRow
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
        assert (info.value.file, info.value.field) == (str(tmp_path / "d" / "frames.csv"), field)
        assert list(tmp_path.iterdir()) == []

    def test_meta_a_reader_would_reject_is_refused(self, tmp_path: Path) -> None:
        meta = make_meta()
        bad = DriveMeta(meta.name, meta.kind, meta.fps, replace(meta.camera, k_x_m_per_px=-1.0))
        with pytest.raises(BadInputError) as info:
            write_drive_folder(tmp_path / "d", bad, make_frames(1), [make_png(0)])
        assert (info.value.file, info.value.field) == (str(tmp_path / "d" / "drive.json"), "camera.k_x")
        with pytest.raises(BadInputError) as info:
            write_drive_folder(tmp_path / "d", replace(meta, fps=float("nan")), make_frames(1), [make_png(0)])
        assert info.value.field == "fps"
        hom = ((1.0, 0.0, 0.0), (0.0, float("inf"), 0.0), (0.0, 0.0, 1.0))
        with pytest.raises(BadInputError) as info:
            camera = replace(meta.camera, ground_homography=hom)
            write_drive_folder(tmp_path / "d", replace(meta, camera=camera), make_frames(1), [make_png(0)])
        assert info.value.field == "camera.ground_homography"
        assert list(tmp_path.iterdir()) == []

    def test_folder_gets_ordinary_permissions(self, tmp_path: Path) -> None:
        write_sample(tmp_path / "d")
        assert (tmp_path / "d").stat().st_mode & 0o777 == (tmp_path / "d" / "frames").stat().st_mode & 0o777

    def test_groundings_of_absent_frames_are_refused(self, tmp_path: Path) -> None:
        with pytest.raises(BadInputError, match=r"not in frames\.csv"):
            write_drive_folder(
                tmp_path / "d", make_meta(), make_frames(2), [make_png(0)] * 2, [GroundingRow(9, 0.0, 0.0)]
            )


@pytest.fixture
def drive(tmp_path: Path) -> Path:
    """A valid drive folder of five frames with groundings, to be broken by each test."""
    out = tmp_path / "drive"
    write_sample(out)
    return out


def edit(file: Path, old: str, new: str) -> None:
    text = file.read_text()
    assert old in text, f"{old!r} not in {file}"
    file.write_text(text.replace(old, new, 1))


def read_error(path: Path) -> BadInputError:
    with pytest.raises(BadInputError) as info:
        read_drive_folder(path)
    return info.value


class TestMissingPieces:
    def test_missing_folder(self, tmp_path: Path) -> None:
        err = read_error(tmp_path / "nowhere")
        assert err.file == str(tmp_path / "nowhere")
        assert "does not exist" in str(err)

    @pytest.mark.parametrize("name", ["drive.json", "frames.csv"])
    def test_missing_file(self, drive: Path, name: str) -> None:
        (drive / name).unlink()
        err = read_error(drive)
        assert err.file == str(drive / name)
        assert "missing" in err.reason

    def test_missing_frames_folder(self, drive: Path) -> None:
        for f in (drive / "frames").iterdir():
            f.unlink()
        (drive / "frames").rmdir()
        assert read_error(drive).file == str(drive / "frames")

    def test_missing_frame_file_names_the_row(self, drive: Path) -> None:
        (drive / "frames" / "000003.png").unlink()
        err = read_error(drive)
        assert (err.file, err.line, err.field) == (str(drive / "frames.csv"), 5, "frame")
        assert "000003.png" in err.reason

    def test_two_files_for_one_frame(self, drive: Path) -> None:
        (drive / "frames" / "000002.jpg").write_bytes(make_jpeg(0))
        err = read_error(drive)
        assert (err.line, err.field) == (4, "frame")
        assert "000002.jpg" in err.reason and "000002.png" in err.reason

    def test_groundings_file_is_optional(self, drive: Path) -> None:
        (drive / "groundings.csv").unlink()
        assert read_drive_folder(drive).groundings == []


class TestDriveJsonErrors:
    """Each broken drive.json names the file, the line and the key (drive.json's layout is fixed)."""

    @pytest.mark.parametrize(
        ("old", "new", "line", "field", "words"),
        [
            ('"kind": "mapping",', '"kind": "mapping"', 5, "kind", "invalid JSON"),
            ('"fps": 10.0', '"fps": NaN', 5, "fps", "NaN"),
            ("driftmap-drive/1", "driftmap-drive/2", 2, "format", "driftmap-drive/1"),
            ('"kind": "mapping"', '"kind": "survey"', 4, "kind", "mapping, localisation"),
            ('"fps": 10.0', '"fps": 0', 5, "fps", "positive"),
            ('"fps": 10.0', '"fps": "10"', 5, "fps", "finite number"),
            ('"width": 32', '"width": "32"', 7, "camera.width", "integer"),
            ('"k_x": 0.30000000000000004', '"k_x": [1]', 10, "camera.k_x", "finite number"),
            ('"forward_sign": -1', '"forward_sign": 0', 14, "camera.forward_sign", "1 or -1"),
            (
                '"ground_roi": [4, 12, 24, 10]',
                '"ground_roi": [4, 12, 29, 10]',
                9,
                "camera.ground_roi",
                "32x24",
            ),
            (
                '"ground_roi": [4, 12, 24, 10]',
                '"ground_roi": [4, 12, 24]',
                9,
                "camera.ground_roi",
                "4 integers",
            ),
            ('"y_h": 4.000000000000001,', '"y_h": 4.0, "y_h": 5.0,', 13, "y_h", "duplicate"),
        ],
    )
    def test_bad_value(
        self, drive: Path, old: str, new: str, line: int, field: str | None, words: str
    ) -> None:
        edit(drive / "drive.json", old, new)
        err = read_error(drive)
        assert (err.file, err.line, err.field) == (str(drive / "drive.json"), line, field)
        assert words in err.reason

    def test_missing_camera_key(self, drive: Path) -> None:
        edit(drive / "drive.json", '"y_c": -0.7,', "")
        err = read_error(drive)
        assert (err.line, err.field) == (6, "camera.y_c")

    def test_missing_top_level_key(self, drive: Path) -> None:
        edit(drive / "drive.json", '"name": "east-mapping-1",', "")
        assert read_error(drive).field == "name"


class TestFramesCsvErrors:
    @pytest.mark.parametrize(
        ("old", "new", "line", "field", "words"),
        [
            ("frame,t,x,y,yaw", "frame,time,x,y,yaw", 1, "t", "header"),
            ("frame,t,x,y,yaw", "frame,t,x,y", 1, "yaw", "header"),
            ("frame,t,x,y,yaw", "frame,t,x,y,yaw,z", 1, "z", "header"),
            ("\n2,0.2,", "\n2.5,0.2,", 4, "frame", "integer"),
            ("\n2,0.2,", "\nabc,0.2,", 4, "frame", "integer"),
            ("\n2,0.2,", "\n2,zero,", 4, "t", "finite number"),
            ("\n2,0.2,", "\n2,nan,", 4, "t", "finite number"),
            ("\n1,0.1,12.41", "\n1,0.1,inf", 3, "x", "finite number"),
            ("\n1,0.1,12.41", "\n1,0.1,1e999", 3, "x", "finite number"),
            ("\n1,0.1,12.41,", "\n1,0.1,,", 3, "x", "all of x, y, yaw"),
            ("\n3,0.3,", "\n1,0.3,", 5, "frame", "twice"),
            ("\n3,0.3,", "\n3,0.2,", 5, "t", "increase"),
            ("\n2,0.2,", "\n-2,0.2,", 4, "frame", "negative"),
            ("\n2,0.2,12.51,", "\n2,0.2,12.51,1,", 4, "(extra)", "cells"),
            ("\n2,0.2,12.51,", '\n2,"0.2,12.51,', 4, None, "quoting"),
        ],
    )
    def test_bad_row(self, drive: Path, old: str, new: str, line: int, field: str | None, words: str) -> None:
        edit(drive / "frames.csv", old, new)
        err = read_error(drive)
        assert (err.file, err.line, err.field) == (str(drive / "frames.csv"), line, field)
        assert words in err.reason

    def test_empty_drive(self, drive: Path) -> None:
        (drive / "frames.csv").write_text("frame,t,x,y,yaw\n")
        err = read_error(drive)
        assert (err.line, err.field) == (1, "frame")
        assert "no frames" in err.reason

    def test_empty_file(self, drive: Path) -> None:
        (drive / "frames.csv").write_text("")
        assert (read_error(drive).line, read_error(drive).field) == (1, "header")

    def test_header_without_truth_is_accepted(self, drive: Path) -> None:
        (drive / "frames.csv").write_text("frame,t\r\n0,0\r\n1,0.5\r\n\r\n")
        (drive / "groundings.csv").unlink()
        assert read_drive_folder(drive).frames == [FrameRow(0, 0.0), FrameRow(1, 0.5)]

    def test_blank_lines_keep_line_numbers(self, drive: Path) -> None:
        (drive / "frames.csv").write_text("frame,t\n\n0,0\n\n0,1\n")
        assert read_error(drive).line == 5


class TestGroundingsErrors:
    @pytest.mark.parametrize(
        ("text", "line", "field", "words"),
        [
            ("frame,x\n0,1\n", 1, "y", "header"),
            ("frame,x,y\n0,1,2\n9,1,2\n", 3, "frame", "not in frames.csv"),
            ("frame,x,y\n0,1,2\n0,1,3\n", 3, "frame", "twice"),
            ("frame,x,y\n0,1,\n", 2, "y", "finite number"),
        ],
    )
    def test_bad_groundings(self, drive: Path, text: str, line: int, field: str, words: str) -> None:
        (drive / "groundings.csv").write_text(text)
        err = read_error(drive)
        assert (err.file, err.line, err.field) == (str(drive / "groundings.csv"), line, field)
        assert words in err.reason


class TestFrameImages:
    def frame_error(self, drive: Path) -> BadInputError:
        folder = read_drive_folder(drive)
        with pytest.raises(BadInputError) as info:
            list(iter_frame_images(folder))
        return info.value

    def test_png_cut_in_half(self, drive: Path) -> None:
        file = drive / "frames" / "000002.png"
        data = file.read_bytes()
        file.write_bytes(data[: len(data) // 2])
        err = self.frame_error(drive)
        assert err.file == str(file)
        assert "truncated" in err.reason

    def test_frame_of_another_size_names_both_sizes(self, drive: Path) -> None:
        file = drive / "frames" / "000004.png"
        file.write_bytes(make_png(0, width=30, height=24))
        err = self.frame_error(drive)
        assert err.file == str(file)
        assert "30x24" in err.reason and "32x24" in err.reason

    def test_garbage_file(self, drive: Path) -> None:
        (drive / "frames" / "000000.png").write_bytes(b"not an image at all")
        assert "not a PNG or JPEG" in self.frame_error(drive).reason

    def test_colour_frames_are_accepted(self, tmp_path: Path) -> None:
        images = [make_png(i, channels=3) for i in range(2)]
        write_drive_folder(tmp_path / "d", make_meta(), make_frames(2), images)
        assert [d for _, d in iter_frame_images(read_drive_folder(tmp_path / "d"))] == images


FINITE = st.floats(allow_nan=False, allow_infinity=False)
TIMES = st.floats(-MAX_ABS_T_S, MAX_ABS_T_S)  # frames.csv refuses larger times


@st.composite
def frame_rows(draw: st.DrawFn) -> list[FrameRow]:
    numbers = draw(st.lists(st.integers(0, 10**7), min_size=1, max_size=20, unique=True))
    times = sorted(draw(st.lists(TIMES, min_size=len(numbers), max_size=len(numbers), unique=True)))
    rows = []
    for frame, t in zip(numbers, times, strict=True):
        truth = draw(st.none() | st.tuples(FINITE, FINITE, FINITE))
        rows.append(FrameRow(frame, t, *(truth or (None, None, None))))
    return rows


class TestFramesCsvProperties:
    @given(frame_rows())
    def test_rows_round_trip_exactly(self, rows: list[FrameRow]) -> None:
        text = frames_text(rows)
        assert parse_frames_csv(text, "frames.csv") == rows
        assert frames_text(parse_frames_csv(text, "frames.csv")) == text

    @pytest.mark.parametrize(
        ("row", "field"),
        [("0,1e11", "t"), ("0,-1e300", "t"), (f"{2**63},1", "frame"), (f"{2**31},1", "frame")],
    )
    def test_values_the_store_cannot_hold_are_named(self, row: str, field: str) -> None:
        with pytest.raises(BadInputError) as info:
            parse_frames_csv(f"frame,t\n{row}\n", "frames.csv")
        assert (info.value.file, info.value.line, info.value.field) == ("frames.csv", 2, field)

    @settings(max_examples=200)
    @given(st.lists(st.text(alphabet=',.-+e0123456789naif "\r', max_size=30), max_size=6))
    def test_garbage_lines_give_bad_input(self, lines: list[str]) -> None:
        text = "frame,t,x,y,yaw\n" + "\n".join(lines)
        try:
            rows = parse_frames_csv(text, "frames.csv")
        except BadInputError as exc:
            assert exc.file == "frames.csv" and exc.line is not None
        else:
            assert rows

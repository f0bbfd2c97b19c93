"""2-D g2o / TORO pose-graph files: parsing, errors naming file, line and field, conversion to chains."""

from __future__ import annotations

from pathlib import Path

import gtsam
import numpy as np
import pytest

from driftmap.errors import BadInputError
from driftmap.formats.g2o import (
    G2oGraph,
    g2o_text,
    parse_g2o,
    read_g2o,
    read_pose_table,
    relative_poses,
    to_pose_graph,
)
from tests.outside_data import SHARED_DATA

DATA = SHARED_DATA / "posegraphs"

G2O = """\
# a square with one loop closure
VERTEX_SE2 0 0 0 0
VERTEX_SE2 1 1.0 0.0 1.5707963
FIX 0
EDGE_SE2 0 1 1.0 0.0 1.5707963 100 1 2 200 3 400
EDGE_SE2 1 2 1.0 0.0 1.5707963 100 0 0 100 0 1000
EDGE_SE2 2 0 1.4142 0.0 -2.3561945 10 0 0 10 0 50   # closure
VERTEX_SE2 2 1.0 1.0 3.1415926
"""


def assert_read_by_gtsam(g: G2oGraph, factors: gtsam.NonlinearFactorGraph, initial: gtsam.Values) -> None:
    """GTSAM's reading of ``g``'s file holds its poses, and one between-factor per edge with its measurement
    and information."""
    assert initial.size() == len(g.vertex_ids)
    for v, wTi in zip(g.vertex_ids, g.wTi, strict=True):
        pose = initial.atPose2(int(v))
        np.testing.assert_allclose([pose.x(), pose.y(), pose.theta()], wTi, atol=1e-12)
    assert factors.size() == g.edge_ij.shape[0]
    for k, ((i, j), iTj, info) in enumerate(zip(g.edge_ij, g.iTj, g.information, strict=True)):
        factor = factors.at(k)
        assert factor.keys() == [int(g.vertex_ids[i]), int(g.vertex_ids[j])]
        measured = factor.measured()
        np.testing.assert_allclose([measured.x(), measured.y(), measured.theta()], iTj, atol=1e-12)
        R = factor.noiseModel().R()  # information = R^T R
        np.testing.assert_allclose(R.T @ R, info, rtol=1e-9, atol=1e-9)


def bad(text: str) -> BadInputError:
    with pytest.raises(BadInputError) as caught:
        parse_g2o(text, "graph.g2o")
    return caught.value


class TestParse:
    def test_vertices_edges_information_and_fix(self) -> None:
        g = parse_g2o(G2O)
        np.testing.assert_array_equal(g.vertex_ids, [0, 1, 2])
        np.testing.assert_allclose(g.wTi[2], [1.0, 1.0, 3.1415926])
        np.testing.assert_array_equal(g.edge_ij, [[0, 1], [1, 2], [2, 0]])
        np.testing.assert_allclose(g.iTj[2], [1.4142, 0.0, -2.3561945])
        np.testing.assert_allclose(g.information[0], [[100, 1, 2], [1, 200, 3], [2, 3, 400]])
        np.testing.assert_array_equal(g.edge_lines, [5, 6, 7])
        np.testing.assert_array_equal(g.fixed, [0])

    def test_toro_records_read_like_g2o(self) -> None:
        toro = "VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nEDGE2 0 1 1 0 0 100 1 200 400 2 3\n"
        g = parse_g2o(toro)
        np.testing.assert_allclose(g.information[0], [[100, 1, 2], [1, 200, 3], [2, 3, 400]])

    def test_ids_need_not_be_contiguous(self) -> None:
        g = parse_g2o("VERTEX_SE2 10 0 0 0\nVERTEX_SE2 4 1 0 0\nEDGE_SE2 4 10 1 0 0 1 0 0 1 0 1\n")
        np.testing.assert_array_equal(g.vertex_ids, [4, 10])
        np.testing.assert_array_equal(g.edge_ij, [[0, 1]])


class TestErrors:
    @pytest.mark.parametrize(
        ("text", "line", "field", "words"),
        [
            ("VERTEX_SE2 0 0 0\n", 1, None, "needs 4 values"),
            ("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0\n", 2, None, "needs 11 values"),
            ("VERTEX_SE2 0 0 x 0\n", 1, "y", "not a number"),
            ("VERTEX_SE2 0 0 0 nan\n", 1, "theta", "not finite"),
            ("VERTEX_SE2 a 0 0 0\n", 1, "id", "not a vertex id"),
            ("VERTEX_SE2 -1 0 0 0\n", 1, "id", "negative"),
            ("VERTEX_SE2 0 0 0 0\n\nVERTEX_SE2 0 1 0 0\n", 3, "id", "defined twice (first on line 1)"),
            ("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 7 1 0 0 1 0 0 1 0 1\n", 2, "id_j", "vertex 7 is not defined"),
            ("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 0 1 0 0 1 0 0 1 0 1\n", 2, "id_j", "itself"),
            (
                "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 0 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 -1 0 1\n",
                3,
                "information",
                "positive definite",
            ),
            ("VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 1 0 0 1 0 0 1 0 inf\n", 2, "I33", "not finite"),
            ("VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\n", 1, None, "3-D"),
            ("VERTEX_XY 5 1 2\n", 1, None, "landmark"),
            ("VERTEX_SE2 0 0 0 0\nPARAMS_SE2OFFSET 0 0 0 0\n", 2, None, "unknown record type"),
            ("VERTEX_SE2 0 0 0 0\nFIX\n", 2, None, "FIX needs"),
            ("VERTEX_SE2 0 0 0 0\nFIX 3\n", 2, "id", "vertex 3 is not defined"),
            ("# nothing\n", None, None, "no VERTEX_SE2"),
        ],
    )
    def test_bad_lines_name_file_line_and_field(
        self, text: str, line: int | None, field: str | None, words: str
    ) -> None:
        error = bad(text)
        assert error.file == "graph.g2o"
        assert error.line == line
        assert error.field == field
        assert words in str(error)
        assert str(error).startswith("graph.g2o")

    def test_unreadable_file_names_it(self, tmp_path: Path) -> None:
        with pytest.raises(BadInputError) as caught:
            read_g2o(tmp_path / "missing.g2o")
        assert caught.value.file == str(tmp_path / "missing.g2o")


class TestFiles:
    def test_read_g2o_and_pose_table(self, tmp_path: Path) -> None:
        path = tmp_path / "square.g2o"
        path.write_text(G2O, encoding="utf-8")
        assert read_g2o(path).edge_ij.shape == (3, 2)
        table = tmp_path / "gt.dat"
        table.write_text("0 0 0\n1.0 0.5 0.1\n\n", encoding="utf-8")
        np.testing.assert_allclose(read_pose_table(table), np.array([[0.0, 0.0, 0.0], [1.0, 0.5, 0.1]]))
        table.write_text("0 0 0\n1.0 0.5\n", encoding="utf-8")
        with pytest.raises(BadInputError) as caught:
            read_pose_table(table)
        assert caught.value.line == 2

    @pytest.mark.skipif(not DATA.exists(), reason="shared/data is absent")
    @pytest.mark.parametrize(
        ("name", "poses", "edges"),
        [
            ("M3500_olson", 3500, 5598),
            ("intel_sesync", 1728, 2512),
            ("city10000", 10000, 20687),
            ("MITb", 808, 827),
        ],
    )
    def test_benchmark_files(self, name: str, poses: int, edges: int) -> None:
        g = read_g2o(DATA / f"{name}.g2o")
        assert g.wTi.shape == (poses, 3) and g.edge_ij.shape == (edges, 2)
        chains, closures = to_pose_graph(g)
        assert len(chains) == 1 and chains[0].num_frames == poses
        assert len(closures) == edges - (poses - 1)


class TestToPoseGraph:
    def test_consecutive_edges_are_odometry_and_gaps_break_chains(self) -> None:
        text = "".join(f"VERTEX_SE2 {i} {i} 0 0\n" for i in range(5))
        text += "EDGE_SE2 0 1 1 0 0 4 0 0 4 0 9\n"
        text += "EDGE_SE2 1 2 1 0 0 4 0 0 4 0 9\n"
        text += "EDGE_SE2 0 1 1.1 0 0 1 0 0 1 0 1\n"  # a second 0 -> 1 edge: a closure
        text += "EDGE_SE2 3 4 1 0 0 4 0 0 4 0 9\n"  # no 2 -> 3 edge: a new chain starts at vertex 3
        text += "EDGE_SE2 4 0 -4 0 0 1 0 0 1 0 1\n"
        chains, closures = to_pose_graph(parse_g2o(text))
        assert [c.num_frames for c in chains] == [3, 2]
        np.testing.assert_allclose(chains[1].wTi_init, [[3, 0, 0], [4, 0, 0]])  # type: ignore[arg-type]
        assert chains[0].information is not None
        np.testing.assert_allclose(chains[0].information[0], np.diag([4.0, 4.0, 9.0]))
        assert [(c.a, c.b) for c in closures] == [((0, 0), (0, 1)), ((1, 1), (0, 0))]
        assert closures[0].aTb == (1.1, 0.0, 0.0)


class TestWriter:
    def test_a_written_graph_reads_back_identical(self) -> None:
        g = parse_g2o(G2O + "FIX 0\n")
        again = parse_g2o(g2o_text(g, ["a comment"]))
        for field in ("vertex_ids", "wTi", "edge_ij", "iTj", "information", "fixed"):
            np.testing.assert_array_equal(getattr(again, field), getattr(g, field))

    def test_gtsam_reads_it_back(self, tmp_path: Path) -> None:
        g = parse_g2o(G2O)
        path = tmp_path / "graph.g2o"
        path.write_text(g2o_text(g, ["site north, version 3", "second comment"]))
        factors, initial = gtsam.readG2o(str(path), False)
        assert_read_by_gtsam(g, factors, initial)

    def test_relative_poses_are_the_pose_of_j_in_i(self) -> None:
        wTi = np.array([[1.0, 2.0, np.pi / 2], [1.0, 5.0, -np.pi / 2 + 0.1]])
        iTj = relative_poses(wTi, np.array([[0, 1]]))
        np.testing.assert_allclose(iTj, [[3.0, 0.0, -np.pi + 0.1]], atol=1e-12)

    def test_non_finite_poses_are_refused(self) -> None:
        g = parse_g2o(G2O)
        broken = G2oGraph(**{**vars(g), "wTi": np.full_like(g.wTi, np.nan)})
        with pytest.raises(ValueError, match="non-finite"):
            g2o_text(broken)

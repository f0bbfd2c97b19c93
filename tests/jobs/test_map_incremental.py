"""Incremental map builds as jobs: the odometry pieces a build keeps, reused by the next build of the site.

On the mini site (two mapping drives of 100 frames, one segment each) on a real database: a build after no
change prepares nothing and gives the same map (its pose graph started from the last version's poses); a
build after a new mapping drive prepares only it and equals a full build (to the solver's tolerance), its
SESAME database scoring only pairs it has not seen and, once the search's basis keyframes are kept, its
loop-closure search scoring only the new drive's keyframes; a moved grounding
re-solves the graph from the kept odometry; a full build prepares everything and replaces the kept pieces;
deleting the site leaves no piece, no kept search or scores and no blob.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sqlalchemy import select

from driftmap.core.mapping.pipeline import MAP_PRESETS, MAPPING_FAST
from driftmap.jobs.queue import JobQueue
from driftmap.services import deletion, loop_searches
from driftmap.services import groundings as grounding_service
from driftmap.services import jobs as job_service
from driftmap.services import sites as site_service
from driftmap.store.job_models import Job
from driftmap.store.models import Drive, Grounding, MapDatabaseScores, MapLoopSearch, MapPiece, MapVersion
from driftmap.store.storage import Storage
from tests.jobs.mini_site import drive_folders
from tests.sim_site import create_site, import_folders, version_poses

GROUNDING_SHIFT_M = 5.0
"""How far the test moves a surveyed point: far beyond the graph's noise."""


def _import(storage: Storage, site_dir: Path, folders: list[Path], create: bool) -> None:
    if create:
        create_site(storage, site_dir, "tiny")
    import_folders(storage, "tiny", folders)


def _build(storage: Storage, queue: JobQueue, **args: Any) -> tuple[MapVersion, list[Job]]:
    """Run a ``map.build`` job of the site; its version and subtasks."""
    with storage.db.session() as session:
        site_id = site_service.get_site(session, "tiny").id
        job_id = job_service.submit(
            session,
            queue.enqueue,
            "map.build",
            {"preset": "fast", **args},
            site_id=site_id,
            created_by="test",
        ).id
    with storage.db.session() as session:
        job = job_service.get_job(session, job_id)
        assert job.status == "succeeded", job.error
        version = session.get(MapVersion, job.result["map_version_id"])
        assert version is not None
        return version, job_service.children(session, job_id)


def _poses(storage: Storage, version: MapVersion) -> np.ndarray:
    """(F, 3) [x_m, y_m, yaw_rad] of the version, frame by frame."""
    return version_poses(storage, version.id)


def _kept(storage: Storage) -> dict[str, str]:
    with storage.db.session() as session:
        return {k: s for k, s in session.execute(select(MapPiece.piece_key, MapPiece.blob_sha256))}


def _search(storage: Storage) -> MapLoopSearch:
    """The site's kept loop-closure search."""
    with storage.db.session() as session:
        return session.scalars(select(MapLoopSearch)).one()


def _scores(storage: Storage) -> MapDatabaseScores:
    """The site's kept SESAME database pair scores."""
    with storage.db.session() as session:
        return session.scalars(select(MapDatabaseScores)).one()


def _reuse(version: MapVersion) -> tuple[int, int]:
    return int(version.stats["segments_reused"]), int(version.stats["segments_prepared"])


class TestIncrementalBuild:
    def test_a_build_after_no_change_prepares_nothing_and_gives_the_same_map(
        self, storage: Storage, queue: JobQueue, mini_site: Path
    ) -> None:
        _import(storage, mini_site, drive_folders(mini_site, "map"), create=True)
        first, subtasks = _build(storage, queue)
        assert _reuse(first) == (0, 2) and sum(j.kind == "map.drive" for j in subtasks) == 2
        kept = _kept(storage)
        assert len(kept) == 2 and all(storage.blobs.exists(sha) for sha in kept.values())
        second, subtasks = _build(storage, queue)
        assert _reuse(second) == (2, 0) and not subtasks  # no odometry, no loop-closure query to score
        assert second.stats["loop_queries_reused"] == second.stats["keyframes"] == first.stats["keyframes"]
        np.testing.assert_array_equal(_poses(storage, second), _poses(storage, first))  # the same solve
        assert _kept(storage) == kept
        assert first.stats["database_pairs_reused"] == 0 < first.stats["database_pairs_scored"]
        # Same poses, same nodes: every comparison of the SESAME database is looked up.
        assert second.stats["database_pairs_scored"] == 0 < second.stats["database_pairs_reused"]
        assert second.stats["reference_frames"] == first.stats["reference_frames"]

    def test_a_new_drive_is_the_only_one_prepared_and_the_map_equals_a_full_build(
        self, storage: Storage, queue: JobQueue, mini_site: Path
    ) -> None:
        folders = drive_folders(mini_site, "map")
        assert len(folders) == 2
        _import(storage, mini_site, folders[:1], create=True)
        alone, _subtasks = _build(storage, queue)
        alone_scores = _scores(storage)
        _import(storage, mini_site, folders[1:], create=False)
        grown, subtasks = _build(storage, queue)
        assert _reuse(alone) == (0, 1) and _reuse(grown) == (1, 1)
        grown_scores = _scores(storage)  # the first drive's pairs looked up, the new drive's scored
        assert grown.stats["database_pairs_reused"] > 0 and grown.stats["database_pairs_scored"] > 0
        assert grown_scores.drives[:1] == alone_scores.drives and len(grown_scores.drives) == 2
        assert storage.blobs.exists(grown_scores.scores_sha256)
        assert not storage.blobs.exists(alone_scores.scores_sha256)  # replaced, dropped
        assert [j.args["drive_id"] for j in subtasks if j.kind == "map.drive"] == [max(_drive_ids(storage))]
        kept = _kept(storage)
        full, subtasks = _build(storage, queue, full=True)
        assert _reuse(full) == (0, 2) and sum(j.kind == "map.drive" for j in subtasks) == 2
        assert full.stats["database_pairs_reused"] == 0
        incremental, rebuilt = _poses(storage, grown), _poses(storage, full)
        assert incremental.shape == rebuilt.shape == (200, 3)
        # Planned afresh like the full build's (the site has fewer keyframes than the search's basis takes):
        # the same closures, the same graph solved from the same start: the same map, bit for bit.
        np.testing.assert_array_equal(incremental, rebuilt)
        for name in ("closures_found", "closures_accepted", "nodes", "reference_frames"):
            assert grown.stats[name] == full.stats[name], name
        replaced = _kept(storage)  # the full build's pieces replace the kept ones, whose blobs are gone
        assert replaced.keys() == kept.keys()
        assert all(storage.blobs.exists(sha) for sha in replaced.values())
        assert not any(storage.blobs.exists(sha) for sha in set(kept.values()) - set(replaced.values()))

    def test_a_new_drive_s_keyframes_are_the_only_loop_closure_queries_scored(
        self, storage: Storage, queue: JobQueue, mini_site: Path, monkeypatch: pytest.MonkeyPatch
    ) -> None:
        # Keyframes every 0.25 m in blocks of 8, one block to a map.loops subtask: several blocks per drive.
        # The basis from the first drive's 64 keyframes (of 133): the search of both resumes the first's.
        loops = replace(MAPPING_FAST.loops, coarse_block=8, basis_keyframes=64)
        params = replace(MAPPING_FAST, keyframe_spacing_m=0.25, loops=loops)
        monkeypatch.setitem(MAP_PRESETS, "fast", params)
        monkeypatch.setattr(loop_searches, "QUERIES_PER_BLOCK", 8)
        folders = drive_folders(mini_site, "map")
        _import(storage, mini_site, folders[:1], create=True)
        alone, _subtasks = _build(storage, queue)
        first = _search(storage)
        _import(storage, mini_site, folders[1:], create=False)
        grown, subtasks = _build(storage, queue)
        second = _search(storage)
        reused, keyframes = grown.stats["loop_queries_reused"], grown.stats["keyframes"]
        assert (alone.stats["loop_queries_reused"], alone.stats["loop_queries_scored"]) == (
            0,
            alone.stats["keyframes"],
        )
        assert (
            0 < reused <= alone.stats["keyframes"]
            and grown.stats["loop_queries_scored"] == keyframes - reused
        )
        scored = [(j.args["q0"], j.args["q1"]) for j in subtasks if j.kind == "map.loops"]
        assert scored[0][0] == reused and scored[-1][1] == keyframes  # only the queries after the kept blocks
        assert second.chains[0] == first.chains[0] and len(second.chains) == 2
        assert [b for b in second.blocks if b[1] <= reused] == [b for b in first.blocks if b[1] <= reused]
        # The blobs of the first search the second does not hold are gone; the second's are there.
        dropped = ({first.basis_sha256} | {b[2] for b in first.blocks}) - (
            {second.basis_sha256} | {b[2] for b in second.blocks}
        )
        assert dropped and not any(storage.blobs.exists(sha) for sha in dropped)
        assert all(storage.blobs.exists(sha) for sha in [second.basis_sha256, *(b[2] for b in second.blocks)])
        full, subtasks = _build(storage, queue, full=True)  # a full build searches afresh: the same search
        assert (full.stats["loop_queries_reused"], full.stats["loop_queries_scored"]) == (0, keyframes)
        for name in ("closures_found", "closures_accepted"):
            assert grown.stats[name] == full.stats[name], name
        np.testing.assert_array_equal(_poses(storage, grown), _poses(storage, full))  # the same graph and map

    def test_a_moved_grounding_re_solves_the_graph_from_the_kept_odometry(
        self, storage: Storage, queue: JobQueue, mini_site: Path
    ) -> None:
        _import(storage, mini_site, drive_folders(mini_site, "map"), create=True)
        before, _subtasks = _build(storage, queue)
        with storage.db.session() as session:
            grounding = session.scalars(select(Grounding).order_by(Grounding.id)).first()
            assert grounding is not None
            grounding_service.update_grounding(session, grounding, x_m=grounding.x_m + GROUNDING_SHIFT_M)
        after, subtasks = _build(storage, queue)
        assert _reuse(after) == (2, 0) and not any(j.kind == "map.drive" for j in subtasks)
        moved = np.linalg.norm(_poses(storage, after)[:, :2] - _poses(storage, before)[:, :2], axis=1)
        assert moved.max() > 1.0  # the graph was solved again with the new surveyed point
        full, _subtasks = _build(storage, queue, full=True)
        np.testing.assert_array_equal(_poses(storage, after), _poses(storage, full))

    def test_other_stage_one_parameters_prepare_every_drive_and_replace_the_kept_pieces(
        self, storage: Storage, queue: JobQueue, mini_site: Path, monkeypatch: pytest.MonkeyPatch
    ) -> None:
        _import(storage, mini_site, drive_folders(mini_site, "map"), create=True)
        _build(storage, queue)
        before = _kept(storage)
        database = replace(MAPPING_FAST.database, view_spacing_m=2.0)  # in the pieces' key, cheap to change
        monkeypatch.setitem(MAP_PRESETS, "fast", replace(MAPPING_FAST, database=database))
        other, subtasks = _build(storage, queue)
        assert _reuse(other) == (0, 2) and sum(j.kind == "map.drive" for j in subtasks) == 2
        kept = _kept(storage)
        assert len(kept) == 2 and not kept.keys() & before.keys()
        assert not any(storage.blobs.exists(sha) for sha in before.values())

    def test_deleting_the_site_leaves_no_kept_piece_or_search_and_no_blob(
        self, storage: Storage, queue: JobQueue, mini_site: Path
    ) -> None:
        _import(storage, mini_site, drive_folders(mini_site, "map"), create=True)
        _build(storage, queue)
        kept = _kept(storage)
        search = _search(storage)
        searched = [search.basis_sha256, *(b[2] for b in search.blocks), _scores(storage).scores_sha256]
        assert kept and all(storage.blobs.exists(sha) for sha in searched)
        with storage.db.session() as session:
            candidates = deletion.delete_site(session, site_service.get_site(session, "tiny"))
        deletion.delete_unreferenced_blobs(storage, candidates)
        assert not _kept(storage)
        assert not any(storage.blobs.exists(sha) for sha in [*kept.values(), *searched])
        with storage.db.session() as session:
            assert session.scalars(select(MapLoopSearch)).first() is None
            assert session.scalars(select(MapDatabaseScores)).first() is None


def _drive_ids(storage: Storage) -> list[int]:
    with storage.db.session() as session:
        return list(session.scalars(select(Drive.id)))

"""Grounding routes on a real SQLite file: create, move, delete, residuals of the latest map, CSV in and out."""

from __future__ import annotations

from pathlib import Path

import httpx

from driftmap.formats.csv_exports import parse_groundings_csv
from tests.api.data_helpers import ApiUsers


def _drives(users: ApiUsers, site_id: int, kind: str) -> list[dict[str, object]]:
    return [d for d in users.get(f"/api/sites/{site_id}/drives")["items"] if d["kind"] == kind]


def _put_csv(users: ApiUsers, drive_id: object, text: str, role: str = "surveyor") -> httpx.Response:
    return users.client.put(
        f"/api/drives/{drive_id}/groundings.csv",
        files={"file": ("marks.csv", text.encode(), "text/csv")},
        headers=users.auth(role),
    )


class TestSingleGroundings:
    def test_create_move_delete(self, users: ApiUsers, site_id: int) -> None:
        drive = _drives(users, site_id, "mapping")[0]
        created = users.client.post(
            f"/api/drives/{drive['id']}/groundings",
            json={"frame": 40, "x": 10.5, "y": -3.25},
            headers=users.auth("surveyor"),
        )
        assert created.status_code == 201, created.text
        body = created.json()
        assert (body["frame"], body["x_m"], body["y_m"], body["created_by"]) == (40, 10.5, -3.25, "surveyor")
        assert body["residual_m"] is None
        again = users.client.post(
            f"/api/drives/{drive['id']}/groundings",
            json={"frame": 40, "x": 0, "y": 0},
            headers=users.auth("surveyor"),
        )
        assert again.status_code == 409
        moved = users.client.patch(
            f"/api/groundings/{body['id']}", json={"y": -4.0}, headers=users.auth("surveyor")
        )
        assert moved.status_code == 200 and (moved.json()["x_m"], moved.json()["y_m"]) == (10.5, -4.0)
        assert (
            users.client.delete(f"/api/groundings/{body['id']}", headers=users.auth("viewer")).status_code
            == 403
        )
        assert (
            users.client.delete(f"/api/groundings/{body['id']}", headers=users.auth("surveyor")).status_code
            == 204
        )
        assert (
            users.client.patch(
                f"/api/groundings/{body['id']}", json={"y": 1.0}, headers=users.auth("surveyor")
            ).status_code
            == 404
        )

    def test_bad_frames_and_drives_are_refused(self, users: ApiUsers, site_id: int) -> None:
        mapping = _drives(users, site_id, "mapping")[0]
        localisation = _drives(users, site_id, "localisation")[0]
        cases = [
            (mapping["id"], {"frame": 100, "x": 1, "y": 2}, 404),
            (localisation["id"], {"frame": 1, "x": 1, "y": 2}, 422),
            (mapping["id"], {"frame": 1, "x": "east", "y": 2}, 422),
            (999999, {"frame": 1, "x": 1, "y": 2}, 404),
        ]
        for drive_id, body, code in cases:
            response = users.client.post(
                f"/api/drives/{drive_id}/groundings", json=body, headers=users.auth("surveyor")
            )
            assert response.status_code == code, (body, response.text)


class TestResiduals:
    def test_list_shows_residuals_of_the_latest_map(self, users: ApiUsers, site_id: int) -> None:
        listed = users.get(f"/api/sites/{site_id}/groundings")
        assert listed["total"] == 2 and all(g["residual_m"] is None for g in listed["items"])
        response = users.client.post(
            f"/api/sites/{site_id}/maps", json={"preset": "fast"}, headers=users.auth("surveyor")
        )
        assert users.job(response.json()["id"])["status"] == "succeeded"
        drive = _drives(users, site_id, "mapping")[0]
        users.client.post(
            f"/api/drives/{drive['id']}/groundings",
            json={"frame": 60, "x": 1.0, "y": 1.0},
            headers=users.auth("surveyor"),
        )
        listed = users.get(f"/api/sites/{site_id}/groundings")
        built = [g for g in listed["items"] if g["residual_m"] is not None]
        assert len(built) == 2 and {g["map_version"] for g in built} == {1}
        assert all(0 <= g["residual_m"] < 2.0 for g in built)
        newer = [g for g in listed["items"] if g["frame"] == 60]
        assert newer[0]["residual_m"] is None and newer[0]["map_version"] is None
        one_drive = users.get(f"/api/sites/{site_id}/groundings", params={"drive_id": drive["id"]})
        assert {g["drive_id"] for g in one_drive["items"]} == {drive["id"]}


class TestCsv:
    def test_export_then_import_round_trips(self, users: ApiUsers, site_id: int, mini_site: Path) -> None:
        drive = _drives(users, site_id, "mapping")[0]
        exported = users.client.get(f"/api/drives/{drive['id']}/groundings.csv", headers=users.auth("viewer"))
        assert exported.status_code == 200 and exported.headers["content-type"].startswith("text/csv")
        original = (mini_site / "drives" / str(drive["name"]) / "groundings.csv").read_text()
        assert parse_groundings_csv(exported.text, "x") == parse_groundings_csv(original, "y")
        replaced = _put_csv(users, drive["id"], "frame,x,y\n3,1.5,2.5\n7,3.0,4.0\n")
        assert replaced.status_code == 200 and replaced.json()["imported"] == 2
        text = users.client.get(
            f"/api/drives/{drive['id']}/groundings.csv", headers=users.auth("viewer")
        ).text
        assert [g.frame for g in parse_groundings_csv(text, "x")] == [3, 7]
        restored = _put_csv(users, drive["id"], exported.text)
        assert restored.json()["imported"] == len(parse_groundings_csv(original, "y"))

    def test_a_bad_line_is_named_and_nothing_changes(self, users: ApiUsers, site_id: int) -> None:
        drive = _drives(users, site_id, "mapping")[0]
        before = users.get(f"/api/sites/{site_id}/groundings", params={"drive_id": drive["id"]})
        for text, line, field in (
            ("frame,x,y\n1,2.0,3.0\n2,north,3.0\n", 3, "x"),
            ("frame,x,y\n1,2.0,3.0\n500,1.0,1.0\n", 3, "frame"),
            ("frame,x,y\n1,2.0,3.0\n1,2.0,3.0\n", 3, "frame"),
        ):
            response = _put_csv(users, drive["id"], text)
            body = response.json()
            assert response.status_code == 422
            assert (body["file"], body["line"], body["field"]) == ("marks.csv", line, field), body
        assert users.get(f"/api/sites/{site_id}/groundings", params={"drive_id": drive["id"]}) == before
        assert _put_csv(users, drive["id"], "frame,x,y\n", role="viewer").status_code == 403


def _put_site_csv(users: ApiUsers, site_id: int, text: str, role: str = "surveyor") -> httpx.Response:
    return users.client.put(
        f"/api/sites/{site_id}/groundings.csv",
        files={"file": ("control.csv", text.encode(), "text/csv")},
        headers=users.auth(role),
    )


class TestSurveyControl:
    def test_patch_enabled_and_station(self, users: ApiUsers, site_id: int) -> None:
        mark = users.get(f"/api/sites/{site_id}/groundings")["items"][0]
        assert (mark["enabled"], mark["station"]) == (True, None)
        url = f"/api/groundings/{mark['id']}"
        assert (
            users.client.patch(url, json={"enabled": False}, headers=users.auth("viewer")).status_code == 403
        )
        patched = users.client.patch(
            url, json={"enabled": False, "station": "STN-104"}, headers=users.auth("surveyor")
        )
        assert patched.status_code == 200, patched.text
        assert (patched.json()["enabled"], patched.json()["station"], patched.json()["x_m"]) == (
            False,
            "STN-104",
            mark["x_m"],
        )
        kept = users.client.patch(url, json={"y": 1.0}, headers=users.auth("surveyor")).json()
        assert (kept["enabled"], kept["station"]) == (False, "STN-104")
        cleared = users.client.patch(url, json={"station": None}, headers=users.auth("surveyor")).json()
        assert cleared["station"] is None
        bad = users.client.patch(url, json={"station": "S" * 65}, headers=users.auth("surveyor"))
        assert bad.status_code == 422 and "station" in bad.text

    def test_site_control_file_round_trip_roles_and_bad_row(self, users: ApiUsers, site_id: int) -> None:
        url = f"/api/sites/{site_id}/groundings.csv"
        exported = users.client.get(url, headers=users.auth("viewer"))
        assert exported.status_code == 200 and exported.headers["content-type"].startswith("text/csv")
        assert exported.text.splitlines()[0] == "drive,frame,station,x,y,enabled"
        drive = _drives(users, site_id, "mapping")[0]["name"]
        text = f"drive,frame,station,x,y,enabled\n{drive},5,STN-9,1.0,2.0,false\n"
        assert _put_site_csv(users, site_id, text, role="viewer").status_code == 403
        replaced = _put_site_csv(users, site_id, text)
        assert replaced.status_code == 200 and replaced.json() == {"site_id": site_id, "imported": 1}
        assert users.client.get(url, headers=users.auth("viewer")).text == text
        bad = _put_site_csv(users, site_id, text + f"{drive},6,,1.0,2.0,sometimes\n")
        assert bad.status_code == 422
        assert (bad.json()["file"], bad.json()["line"], bad.json()["field"]) == ("control.csv", 3, "enabled")
        assert users.client.get(url, headers=users.auth("viewer")).text == text
        assert _put_site_csv(users, site_id, exported.text).json()["imported"] == 2

    def test_a_build_uses_enabled_groundings_and_summarises_them(self, users: ApiUsers, site_id: int) -> None:
        drive = _drives(users, site_id, "mapping")[0]
        far = users.client.post(
            f"/api/drives/{drive['id']}/groundings",
            json={"frame": 50, "x": 5000.0, "y": 5000.0, "station": "STN-X", "enabled": False},
            headers=users.auth("surveyor"),
        )
        assert far.status_code == 201 and far.json()["enabled"] is False
        response = users.client.post(
            f"/api/sites/{site_id}/maps", json={"preset": "fast"}, headers=users.auth("surveyor")
        )
        assert users.job(response.json()["id"])["status"] == "succeeded"
        residuals = users.get(f"/api/sites/{site_id}/maps/1/residuals")
        assert len(residuals) == 2 and far.json()["id"] not in {r["grounding_id"] for r in residuals}
        assert all(r["enabled"] is True and r["distance_m"] < 2.0 for r in residuals)
        summary = users.get(f"/api/sites/{site_id}/maps/1/residuals/summary")
        distances = [r["distance_m"] for r in residuals]
        overall = summary["overall"]
        assert (summary["version"], overall["count"]) == (1, 2)
        assert overall["max_m"] == max(distances)
        assert abs(overall["mean_m"] - sum(distances) / 2) < 1e-9
        assert overall["mean_m"] <= overall["rms_m"] <= overall["max_m"]
        assert sum(d["stats"]["count"] for d in summary["drives"]) == 2
        csv_text = users.client.get(
            f"/api/sites/{site_id}/maps/1/residuals.csv", headers=users.auth("viewer")
        ).text
        lines = csv_text.splitlines()
        assert lines[0] == "drive,frame,station,x,y,residual_m,enabled" and len(lines) == 3
        assert all(line.endswith(",true") for line in lines[1:])

"""Login, tokens, users management and ``driftmap user add``, on a real SQLite file."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect
from typer.testing import CliRunner

from driftmap.api.app import create_app
from driftmap.api.deps import TOKEN_COOKIE, WS_CLOSE_UNAUTHORIZED
from driftmap.cli import app as cli_app
from driftmap.config import Settings, get_settings
from driftmap.services import security
from driftmap.services import users as user_service
from driftmap.store.access_models import User
from driftmap.store.storage import Storage
from tests.api.access_helpers import PASSWORD, Actors, make_actors


@pytest.fixture
def actors(settings: Settings) -> Iterator[Actors]:
    made = make_actors(settings)
    yield made
    made.client.close()


class TestLogin:
    def test_good_password_gives_a_bearer_token(self, actors: Actors) -> None:
        response = actors.client.post("/api/auth/login", json={"username": "viewer", "password": PASSWORD})
        assert response.status_code == 200
        body = response.json()
        assert body["token_type"] == "bearer" and body["expires_in"] > 0
        me = actors.client.get("/api/auth/me", headers={"Authorization": f"Bearer {body['access_token']}"})
        assert me.json() == {"kind": "user", "id": me.json()["id"], "name": "viewer", "role": "viewer"}

    @pytest.mark.parametrize(("username", "password"), [("viewer", "wrong password"), ("nobody", PASSWORD)])
    def test_bad_credentials_give_401(self, actors: Actors, username: str, password: str) -> None:
        response = actors.client.post("/api/auth/login", json={"username": username, "password": password})
        assert response.status_code == 401
        assert response.json()["detail"] == "wrong user name or password"
        assert "set-cookie" not in response.headers

    def test_login_sets_an_httponly_secure_cookie_that_authenticates(self, settings: Settings) -> None:
        actors = make_actors(settings)
        client = TestClient(actors.app, base_url="https://testserver")
        response = client.post("/api/auth/login", json={"username": "admin", "password": PASSWORD})
        cookie = response.headers["set-cookie"].lower()
        assert "httponly" in cookie and "secure" in cookie and "samesite=strict" in cookie
        assert client.get("/api/users").status_code == 200
        cookie = {"Cookie": f"{TOKEN_COOKIE}={client.cookies[TOKEN_COOKIE]}"}  # what a browser sends to wss:
        with client.websocket_connect("/api/live", headers=cookie) as ws:
            assert ws.receive_json()["type"] == "snapshot"  # no token in the URL, no auth message
        client.post("/api/auth/logout")
        assert client.get("/api/users").status_code == 401
        with (
            client.websocket_connect("/api/live", headers=cookie) as ws,
            pytest.raises(WebSocketDisconnect) as closed,
        ):
            ws.receive_json()
        assert closed.value.code == WS_CLOSE_UNAUTHORIZED  # the logged-out cookie no longer opens a socket

    def test_expired_and_forged_tokens_are_refused(self, actors: Actors, settings: Settings) -> None:
        key = security.secret_key(settings)
        expired = security.issue_token(key, 1, ttl_s=-1.0)
        forged = security.issue_token(b"another key", 1, ttl_s=3600.0)
        for token in (expired, forged):
            response = actors.client.get("/api/auth/me", headers={"Authorization": f"Bearer {token}"})
            assert response.status_code == 401

    def test_a_deleted_user_token_stops_working(self, actors: Actors) -> None:
        me = actors.client.get("/api/auth/me", headers=actors.auth("surveyor")).json()
        assert actors.client.delete(f"/api/users/{me['id']}", headers=actors.auth("admin")).status_code == 204
        assert actors.client.get("/api/auth/me", headers=actors.auth("surveyor")).status_code == 401

    def test_secret_key_is_kept_under_the_data_dir(self, settings: Settings) -> None:
        key = security.secret_key(settings)
        assert (settings.data_dir / "secret_key").is_file()
        assert security.secret_key(settings) == key
        assert security.secret_key(Settings(data_dir=settings.data_dir, secret_key="fixed")) == b"fixed"

    def test_passwords_are_stored_as_argon2_hashes(self, actors: Actors) -> None:
        storage: Storage = actors.app.state.storage
        with storage.db.session() as session:
            stored = session.query(User).filter_by(username="viewer").one().password_hash
        assert stored.startswith("$argon2id$") and PASSWORD not in stored


class TestUsers:
    def test_admin_creates_lists_updates_and_deletes(self, actors: Actors) -> None:
        admin = actors.auth("admin")
        created = actors.client.post(
            "/api/users", json={"username": "ops", "password": "longenough1", "role": "viewer"}, headers=admin
        )
        assert created.status_code == 201 and created.json()["role"] == "viewer"
        uid = created.json()["id"]
        assert "ops" in [u["username"] for u in actors.client.get("/api/users", headers=admin).json()]
        patched = actors.client.patch(f"/api/users/{uid}", json={"role": "surveyor"}, headers=admin)
        assert patched.json()["role"] == "surveyor"
        actors.client.patch(f"/api/users/{uid}", json={"password": "another-secret"}, headers=admin)
        login = actors.client.post("/api/auth/login", json={"username": "ops", "password": "another-secret"})
        assert login.status_code == 200
        assert actors.client.delete(f"/api/users/{uid}", headers=admin).status_code == 204
        assert actors.client.get(f"/api/users/{uid}", headers=admin).status_code == 404

    def test_duplicate_name_is_409_and_short_password_422(self, actors: Actors) -> None:
        admin = actors.auth("admin")
        dup = actors.client.post(
            "/api/users",
            json={"username": "viewer", "password": "longenough1", "role": "viewer"},
            headers=admin,
        )
        assert dup.status_code == 409 and "already exists" in dup.json()["detail"]
        short = actors.client.post(
            "/api/users", json={"username": "x", "password": "short", "role": "viewer"}, headers=admin
        )
        assert short.status_code == 422 and short.json()["field"] == "password"

    def test_the_last_admin_stays(self, actors: Actors) -> None:
        admin = actors.auth("admin")
        me = actors.client.get("/api/auth/me", headers=admin).json()
        demote = actors.client.patch(f"/api/users/{me['id']}", json={"role": "viewer"}, headers=admin)
        assert demote.status_code == 409 and "last active admin" in demote.json()["detail"]
        assert actors.client.delete(f"/api/users/{me['id']}", headers=admin).status_code == 409


class TestUserAddCommand:
    @pytest.fixture
    def data_dir(self, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
        monkeypatch.setenv("DRIFTMAP_DATA_DIR", str(tmp_path / "data"))
        monkeypatch.delenv("DRIFTMAP_DATABASE_URL", raising=False)
        get_settings.cache_clear()
        yield tmp_path / "data"
        get_settings.cache_clear()

    def test_user_add_with_password_on_stdin_can_log_in(self, data_dir: Path) -> None:
        result = CliRunner().invoke(
            cli_app, ["user", "add", "boss", "--role", "admin", "--password-stdin"], input="s3cret-pass\n"
        )
        assert result.exit_code == 0, result.output
        listed = CliRunner().invoke(cli_app, ["user", "list"])
        assert "boss" in listed.output and "admin" in listed.output
        with TestClient(create_app(Settings(data_dir=data_dir))) as client:
            login = client.post("/api/auth/login", json={"username": "boss", "password": "s3cret-pass"})
            assert login.status_code == 200

    def test_bad_role_is_a_clear_error(self, data_dir: Path) -> None:
        result = CliRunner().invoke(
            cli_app, ["user", "add", "x", "--role", "king", "--password-stdin"], input="s3cret-pass\n"
        )
        assert result.exit_code == 2  # a usage error: --role takes one of its choices
        assert "'king' is not one of" in result.output

    def test_prompted_password_must_match(self, data_dir: Path) -> None:
        result = CliRunner().invoke(
            cli_app, ["user", "add", "y", "--role", "viewer"], input="s3cret-pass\ns3cret-pass\n"
        )
        assert result.exit_code == 0, result.output
        storage = Storage.open(Settings(data_dir=data_dir))
        with storage.db.session() as session:
            assert [u.username for u in user_service.list_users(session)] == ["y"]
        storage.close()


def _login(actors: Actors, username: str, password: str = PASSWORD) -> dict[str, str]:
    response = actors.client.post("/api/auth/login", json={"username": username, "password": password})
    assert response.status_code == 200, response.text
    actors.client.cookies.clear()
    return {"Authorization": f"Bearer {response.json()['access_token']}"}


def _me(actors: Actors, headers: dict[str, str]) -> int:
    return actors.client.get("/api/auth/me", headers=headers).status_code


class TestRevocation:
    def test_logout_revokes_every_token_of_the_user(self, actors: Actors) -> None:
        first, second = _login(actors, "viewer"), _login(actors, "viewer")
        assert actors.client.post("/api/auth/logout", headers=first).status_code == 204
        assert (_me(actors, first), _me(actors, second)) == (401, 401)
        assert _me(actors, actors.auth("surveyor")) == 200  # other users keep theirs
        assert _me(actors, _login(actors, "viewer")) == 200  # and a new login works

    def test_an_admin_password_reset_revokes_the_tokens(self, actors: Actors) -> None:
        me = actors.client.get("/api/auth/me", headers=actors.auth("viewer")).json()
        reset = actors.client.patch(
            f"/api/users/{me['id']}", json={"password": "a-new-password"}, headers=actors.auth("admin")
        )
        assert reset.status_code == 200
        assert _me(actors, actors.auth("viewer")) == 401
        assert _me(actors, _login(actors, "viewer", "a-new-password")) == 200

    def test_a_role_change_revokes_the_tokens(self, actors: Actors) -> None:
        me = actors.client.get("/api/auth/me", headers=actors.auth("viewer")).json()
        patched = actors.client.patch(
            f"/api/users/{me['id']}", json={"role": "surveyor"}, headers=actors.auth("admin")
        )
        assert patched.status_code == 200 and patched.json()["role"] == "surveyor"
        assert _me(actors, actors.auth("viewer")) == 401
        again = actors.client.get("/api/auth/me", headers=_login(actors, "viewer")).json()
        assert again["role"] == "surveyor"

    def test_a_revoked_token_cannot_open_a_websocket(self, actors: Actors) -> None:
        viewer = actors.auth("viewer")
        actors.client.post("/api/auth/logout", headers=viewer)
        with (
            actors.client.websocket_connect("/api/live", headers=viewer) as ws,
            pytest.raises(WebSocketDisconnect) as closed,
        ):
            ws.receive_json()
        assert closed.value.code == WS_CLOSE_UNAUTHORIZED


class TestDisable:
    def test_a_disabled_user_is_refused_and_enabled_again(self, actors: Actors) -> None:
        admin = actors.auth("admin")
        me = actors.client.get("/api/auth/me", headers=actors.auth("surveyor")).json()
        disabled = actors.client.patch(f"/api/users/{me['id']}", json={"disabled": True}, headers=admin)
        assert disabled.status_code == 200 and disabled.json()["disabled_at"] is not None
        assert _me(actors, actors.auth("surveyor")) == 401
        login = actors.client.post("/api/auth/login", json={"username": "surveyor", "password": PASSWORD})
        assert login.status_code == 403 and "disabled" in login.json()["detail"]
        enabled = actors.client.patch(f"/api/users/{me['id']}", json={"disabled": False}, headers=admin)
        assert enabled.json()["disabled_at"] is None
        assert _me(actors, _login(actors, "surveyor")) == 200

    def test_an_admin_may_not_disable_or_delete_themself(self, actors: Actors, settings: Settings) -> None:
        storage: Storage = actors.app.state.storage
        with storage.db.session() as session:
            user_service.create_user(session, "admin2", PASSWORD, "admin")  # not the last admin
        admin = actors.auth("admin")
        me = actors.client.get("/api/auth/me", headers=admin).json()
        disable = actors.client.patch(f"/api/users/{me['id']}", json={"disabled": True}, headers=admin)
        assert disable.status_code == 409 and "your own account" in disable.json()["detail"]
        delete = actors.client.delete(f"/api/users/{me['id']}", headers=admin)
        assert delete.status_code == 409 and "your own account" in delete.json()["detail"]
        assert _me(actors, admin) == 200


class TestOwnPassword:
    def test_changing_your_password_revokes_old_tokens_and_answers_a_new_one(self, actors: Actors) -> None:
        old = actors.auth("viewer")
        body = {"current_password": PASSWORD, "new_password": "my-new-password"}
        changed = actors.client.post("/api/auth/password", json=body, headers=old)
        assert changed.status_code == 200, changed.text
        assert _me(actors, old) == 401
        assert _me(actors, {"Authorization": f"Bearer {changed.json()['access_token']}"}) == 200
        assert _me(actors, _login(actors, "viewer", "my-new-password")) == 200

    def test_a_wrong_current_password_is_422(self, actors: Actors) -> None:
        body = {"current_password": "not it at all", "new_password": "my-new-password"}
        wrong = actors.client.post("/api/auth/password", json=body, headers=actors.auth("viewer"))
        assert wrong.status_code == 422 and wrong.json()["field"] == "current_password"
        assert _me(actors, actors.auth("viewer")) == 200


class TestOpenSockets:
    def test_an_open_live_socket_closes_once_its_token_is_revoked(self, actors: Actors) -> None:
        viewer = actors.auth("viewer")
        with actors.client.websocket_connect("/api/live", headers=viewer) as ws:
            assert ws.receive_json()["type"] == "snapshot"
            assert actors.client.post("/api/auth/logout", headers=viewer).status_code == 204
            with pytest.raises(WebSocketDisconnect) as closed:
                ws.receive_json()  # no positions come: the next message is the close, within TOKEN_RECHECK_S
        assert closed.value.code == WS_CLOSE_UNAUTHORIZED and "revoked" in closed.value.reason

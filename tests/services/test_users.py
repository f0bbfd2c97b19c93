"""Tests of driftmap.services.users: the rules that keep the server administrable."""

from __future__ import annotations

import pytest

from driftmap.errors import ConflictError
from driftmap.services import users as user_service
from driftmap.store.storage import Storage

PASSWORD = "long-enough-1"


class TestTheLastAdmin:
    def test_the_only_admin_cannot_be_deleted_demoted_or_disabled(self, storage: Storage) -> None:
        with storage.db.session() as session:
            admin = user_service.create_user(session, "boss", PASSWORD, "admin")
            with pytest.raises(ConflictError, match="'boss' is the last active admin and cannot be deleted"):
                user_service.delete_user(session, admin)
            with pytest.raises(ConflictError, match="cannot be made viewer; make another user admin first"):
                user_service.update_user(session, admin, role="viewer")
            with pytest.raises(ConflictError, match="cannot be disabled"):
                user_service.update_user(session, admin, disabled=True)
            assert (admin.role, admin.disabled_at) == ("admin", None)

    def test_a_disabled_admin_does_not_count(self, storage: Storage) -> None:
        with storage.db.session() as session:
            active = user_service.create_user(session, "boss", PASSWORD, "admin")
            dormant = user_service.create_user(session, "dormant", PASSWORD, "admin")
            user_service.update_user(session, dormant, disabled=True)
            with pytest.raises(ConflictError, match="last active admin"):
                user_service.delete_user(session, active)
            user_service.delete_user(session, dormant)  # a disabled admin may go
            assert [u.username for u in user_service.list_users(session)] == ["boss"]

    def test_with_a_second_admin_either_may_go(self, storage: Storage) -> None:
        with storage.db.session() as session:
            first = user_service.create_user(session, "boss", PASSWORD, "admin")
            second = user_service.create_user(session, "deputy", PASSWORD, "admin")
            user_service.update_user(session, second, role="surveyor", acting_user_id=first.id)
            user_service.update_user(session, second, role="admin", acting_user_id=first.id)
            user_service.delete_user(session, first, acting_user_id=second.id)
            with pytest.raises(ConflictError, match="'deputy' is the last active admin"):
                user_service.update_user(session, second, role="surveyor", acting_user_id=second.id)


class TestYourself:
    def test_an_admin_cannot_delete_or_disable_themself(self, storage: Storage) -> None:
        with storage.db.session() as session:
            first = user_service.create_user(session, "boss", PASSWORD, "admin")
            user_service.create_user(session, "deputy", PASSWORD, "admin")
            with pytest.raises(ConflictError, match="you cannot delete your own account"):
                user_service.delete_user(session, first, acting_user_id=first.id)
            with pytest.raises(ConflictError, match="you cannot disable your own account"):
                user_service.update_user(session, first, disabled=True, acting_user_id=first.id)

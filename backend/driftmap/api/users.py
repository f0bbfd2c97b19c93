"""Users (admins only): list, create, change role or password, disable, delete.

Any change of a user revokes the user's login tokens; an admin cannot disable or delete themself.
"""

from __future__ import annotations

from fastapi import APIRouter, Depends, Request, status

from driftmap.api.deps import ADMIN, AdminDep, SessionDep, forget_principals
from driftmap.api.input_types import Id
from driftmap.api.schemas_access import UserCreate, UserRead, UserUpdate
from driftmap.services import users as user_service

router = APIRouter(prefix="/users", tags=["users"], dependencies=[Depends(ADMIN)])


@router.get("")
def list_users(session: SessionDep) -> list[UserRead]:
    """Every user."""
    return [UserRead.model_validate(u) for u in user_service.list_users(session)]


@router.post("", status_code=status.HTTP_201_CREATED)
def create_user(body: UserCreate, session: SessionDep) -> UserRead:
    """A new user with a role."""
    user = user_service.create_user(session, body.username, body.password, body.role.value)
    return UserRead.model_validate(user)


@router.get("/{user_id}")
def get_user(user_id: Id, session: SessionDep) -> UserRead:
    """One user."""
    return UserRead.model_validate(user_service.get_user(session, user_id))


@router.patch("/{user_id}")
def update_user(
    user_id: Id, body: UserUpdate, session: SessionDep, request: Request, admin: AdminDep
) -> UserRead:
    """Change a user's role or password (a reset), or disable or enable the user; revokes the user's tokens."""
    user = user_service.get_user(session, user_id)
    role = body.role.value if body.role is not None else None
    changed = user_service.update_user(
        session, user, role=role, password=body.password, disabled=body.disabled, acting_user_id=admin.id
    )
    updated = UserRead.model_validate(changed)
    session.commit()
    forget_principals(request)
    return updated


@router.delete("/{user_id}", status_code=status.HTTP_204_NO_CONTENT)
def delete_user(user_id: Id, session: SessionDep, request: Request, admin: AdminDep) -> None:
    """Remove a user (not the last admin, not yourself)."""
    user_service.delete_user(session, user_service.get_user(session, user_id), acting_user_id=admin.id)
    session.commit()
    forget_principals(request)

"""Users (admins only): list, create, change role or password, delete."""

from __future__ import annotations

from fastapi import APIRouter, Depends, Request, status

from driftmap.api.deps import ADMIN, SessionDep, forget_principals
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
def get_user(user_id: int, session: SessionDep) -> UserRead:
    """One user."""
    return UserRead.model_validate(user_service.get_user(session, user_id))


@router.patch("/{user_id}")
def update_user(user_id: int, body: UserUpdate, session: SessionDep, request: Request) -> UserRead:
    """Change a user's role or password."""
    user = user_service.get_user(session, user_id)
    role = body.role.value if body.role is not None else None
    updated = UserRead.model_validate(
        user_service.update_user(session, user, role=role, password=body.password)
    )
    session.commit()
    forget_principals(request)
    return updated


@router.delete("/{user_id}", status_code=status.HTTP_204_NO_CONTENT)
def delete_user(user_id: int, session: SessionDep, request: Request) -> None:
    """Remove a user (not the last admin)."""
    user_service.delete_user(session, user_service.get_user(session, user_id))
    session.commit()
    forget_principals(request)

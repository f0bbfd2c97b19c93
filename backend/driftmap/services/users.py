"""Users of the server: create, list, change role or password, delete, and check a login."""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from driftmap.errors import BadInputError, ConflictError, NotFoundError
from driftmap.services.security import DUMMY_PASSWORD_HASH, hash_password, verify_password
from driftmap.store.access_models import User

ROLES = ("admin", "surveyor", "viewer")
MIN_PASSWORD_LENGTH = 8


def _check_role(role: str) -> str:
    if role not in ROLES:
        raise BadInputError(f"role must be one of {', '.join(ROLES)}, got {role!r}", field="role")
    return role


def _check_password(password: str) -> str:
    if len(password) < MIN_PASSWORD_LENGTH:
        raise BadInputError(f"a password needs at least {MIN_PASSWORD_LENGTH} characters", field="password")
    return password


def create_user(session: Session, username: str, password: str, role: str) -> User:
    """A new user; the name must be unused."""
    username = username.strip()
    if not username or len(username) > 100:
        raise BadInputError("a user name needs 1 to 100 characters", field="username")
    if session.scalar(select(User.id).where(User.username == username)) is not None:
        raise ConflictError(f"a user named {username!r} already exists")
    user = User(
        username=username, password_hash=hash_password(_check_password(password)), role=_check_role(role)
    )
    session.add(user)
    session.flush()
    return user


def get_user(session: Session, user_id: int) -> User:
    """The user with id ``user_id``."""
    user = session.get(User, user_id)
    if user is None:
        raise NotFoundError(f"no user with id {user_id}")
    return user


def list_users(session: Session) -> list[User]:
    """Every user, oldest first."""
    return list(session.scalars(select(User).order_by(User.id)))


def _admins(session: Session) -> int:
    return session.scalar(select(func.count()).select_from(User).where(User.role == "admin")) or 0


def update_user(
    session: Session, user: User, *, role: str | None = None, password: str | None = None
) -> User:
    """Change ``user``'s role and/or password; the last admin cannot lose the role."""
    if role is not None:
        if user.role == "admin" and role != "admin" and _admins(session) <= 1:
            raise ConflictError(f"{user.username!r} is the last admin; make another admin first")
        user.role = _check_role(role)
    if password is not None:
        user.password_hash = hash_password(_check_password(password))
    session.flush()
    return user


def delete_user(session: Session, user: User) -> None:
    """Remove ``user``; the last admin cannot be removed."""
    if user.role == "admin" and _admins(session) <= 1:
        raise ConflictError(f"{user.username!r} is the last admin and cannot be deleted")
    session.delete(user)
    session.flush()


def authenticate(session: Session, username: str, password: str) -> User | None:
    """The user when ``password`` is right, else None (same work whether or not the user exists)."""
    user = session.scalar(select(User).where(User.username == username.strip()))
    if user is None:
        verify_password(DUMMY_PASSWORD_HASH, password)
        return None
    return user if verify_password(user.password_hash, password) else None

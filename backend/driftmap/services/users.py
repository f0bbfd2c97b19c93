"""Users of the server: create, list, change role or password, disable, delete, and check a login.

Changing a user's role or password, disabling the user and logging out raise the user's token generation
(:func:`revoke_tokens`), which makes every login token issued before invalid.
"""

from __future__ import annotations

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from driftmap.errors import BadInputError, ConflictError, NotFoundError
from driftmap.services.security import DUMMY_PASSWORD_HASH, hash_password, verify_password
from driftmap.store.access_models import User
from driftmap.store.models import utc_now

ROLES = ("admin", "surveyor", "viewer")
MIN_PASSWORD_LENGTH = 8
MAX_PASSWORD_LENGTH = (
    1024  # hashing a password costs memory and time whatever its length; a bound keeps it so
)


def _check_role(role: str) -> str:
    if role not in ROLES:
        raise BadInputError(f"role must be one of {', '.join(ROLES)}, got {role!r}", field="role")
    return role


def _check_password(password: str) -> str:
    if not MIN_PASSWORD_LENGTH <= len(password) <= MAX_PASSWORD_LENGTH:
        raise BadInputError(
            f"a password needs {MIN_PASSWORD_LENGTH} to {MAX_PASSWORD_LENGTH} characters", field="password"
        )
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


def _other_active_admins(session: Session, user: User) -> int:
    """How many enabled admins there are besides ``user``."""
    others = (User.role == "admin") & User.disabled_at.is_(None) & (User.id != user.id)
    return session.scalar(select(func.count()).select_from(User).where(others)) or 0


def _refuse_losing_the_last_admin(session: Session, user: User, change: str) -> None:
    """Refuse ``change`` (e.g. "deleted") when ``user`` is the only enabled admin: nobody could administer."""
    if user.role == "admin" and user.disabled_at is None and _other_active_admins(session, user) == 0:
        raise ConflictError(
            f"{user.username!r} is the last active admin and cannot be {change}; make another user admin first"
        )


def revoke_tokens(user: User) -> None:
    """Make every login token of ``user`` issued so far invalid (flushed with the session)."""
    user.token_generation += 1


def update_user(
    session: Session,
    user: User,
    *,
    role: str | None = None,
    password: str | None = None,
    disabled: bool | None = None,
    acting_user_id: int | None = None,
) -> User:
    """Change ``user``'s role, password and/or disabled state; any change revokes the user's tokens.

    The last active admin cannot lose the role or be disabled, and ``acting_user_id`` (the admin making
    the change) cannot disable themself.
    """
    changed = False
    if role is not None and role != user.role:
        new_role = _check_role(role)
        _refuse_losing_the_last_admin(session, user, f"made {new_role}")
        user.role = new_role
        changed = True
    if password is not None:
        user.password_hash = hash_password(_check_password(password))
        changed = True
    if disabled is not None and disabled != (user.disabled_at is not None):
        if disabled:
            if user.id == acting_user_id:
                raise ConflictError("you cannot disable your own account")
            _refuse_losing_the_last_admin(session, user, "disabled")
        user.disabled_at = utc_now() if disabled else None
        changed = True
    if changed:
        revoke_tokens(user)
    session.flush()
    return user


class WrongPasswordError(BadInputError):
    """The current password given for a password change is wrong."""


def change_own_password(session: Session, user: User, current: str, new: str) -> User:
    """A user's own password change: ``current`` must be right; revokes the user's tokens."""
    if not verify_password(user.password_hash, current):
        raise WrongPasswordError("the current password is wrong", field="current_password")
    return update_user(session, user, password=new)


def delete_user(session: Session, user: User, *, acting_user_id: int | None = None) -> None:
    """Remove ``user``; the last active admin cannot be removed, nor ``acting_user_id`` (the admin) themself."""
    if user.id == acting_user_id:
        raise ConflictError("you cannot delete your own account")
    _refuse_losing_the_last_admin(session, user, "deleted")
    session.delete(user)
    session.flush()


def authenticate(session: Session, username: str, password: str) -> User | None:
    """The user when ``password`` is right, else None (same work whether or not the user exists).

    A disabled user with the right password is returned too; the caller refuses it with its own message.
    """
    user = session.scalar(select(User).where(User.username == username.strip()))
    if user is None:
        verify_password(DUMMY_PASSWORD_HASH, password)
        return None
    return user if verify_password(user.password_hash, password) else None

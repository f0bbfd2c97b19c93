"""Log in and out, change your own password, and ask who you are.

Logins are throttled and their password hashing bounded (:mod:`driftmap.services.login_guard`): a refused
login is answered 429 with ``Retry-After``. Logging out and changing the password revoke every login token
of the user (:func:`driftmap.services.users.revoke_tokens`).
"""

from __future__ import annotations

from dataclasses import dataclass

from fastapi import APIRouter, HTTPException, Request, Response, status
from starlette.concurrency import run_in_threadpool

from driftmap.api.deps import TOKEN_COOKIE, ViewerDep, cached_principal, forget_principals
from driftmap.api.problems import problem_responses
from driftmap.api.schemas_access import LoginRequest, Me, PasswordChange, TokenRead
from driftmap.services import security
from driftmap.services import users as user_service
from driftmap.services.login_guard import LoginGuard, LoginRefusedError
from driftmap.store.storage import Storage

router = APIRouter(prefix="/auth", tags=["auth"])
_REFUSED = problem_responses(
    429, descriptions={429: "Too many failed logins (or logins at once); see the Retry-After header."}
)


@dataclass(frozen=True)
class _Checked:
    """The outcome of a password check, read inside its database session."""

    user_id: int
    generation: int
    disabled: bool


def _guard(request: Request) -> LoginGuard:
    guard: LoginGuard = request.app.state.login_guard
    return guard


def _address(request: Request) -> str:
    return request.client.host if request.client is not None else "unknown"


def _too_many(exc: LoginRefusedError) -> HTTPException:
    return HTTPException(status.HTTP_429_TOO_MANY_REQUESTS, str(exc), {"Retry-After": str(exc.retry_after_s)})


def _authenticate(storage: Storage, username: str, password: str) -> _Checked | None:
    with storage.db.session() as session:
        user = user_service.authenticate(session, username, password)
        return (
            None if user is None else _Checked(user.id, user.token_generation, user.disabled_at is not None)
        )


def _issue(request: Request, response: Response, checked: _Checked) -> TokenRead:
    ttl = int(request.app.state.settings.token_ttl_s)
    token = security.issue_token(
        request.app.state.secret_key, checked.user_id, ttl, generation=checked.generation
    )
    response.set_cookie(TOKEN_COOKIE, token, max_age=ttl, httponly=True, secure=True, samesite="strict")
    return TokenRead(access_token=token, expires_in=ttl)


@router.post("/login", responses=_REFUSED)
async def login(body: LoginRequest, request: Request, response: Response) -> TokenRead:
    """Exchange a user name and password for a bearer token (also set as an httponly cookie)."""
    guard, address, storage = _guard(request), _address(request), request.app.state.storage
    try:
        await guard.check(body.username, address)
        checked = await guard.hashing(lambda: _authenticate(storage, body.username, body.password))
    except LoginRefusedError as exc:
        raise _too_many(exc) from None
    if checked is None:
        await guard.failed(body.username, address)
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED, "wrong user name or password", {"WWW-Authenticate": "Bearer"}
        )
    if checked.disabled:
        raise HTTPException(status.HTTP_403_FORBIDDEN, "this user is disabled; ask an admin")
    await guard.succeeded(body.username)
    return _issue(request, response, checked)


def _revoke(storage: Storage, user_id: int) -> None:
    with storage.db.session() as session:
        user_service.revoke_tokens(user_service.get_user(session, user_id))


@router.post("/logout", status_code=status.HTTP_204_NO_CONTENT)
async def logout(request: Request, response: Response) -> None:
    """Revoke every login token of the caller (if logged in, on every device) and forget the login cookie."""
    principal = await cached_principal(request)
    if principal is not None and principal.kind == "user":
        await run_in_threadpool(_revoke, request.app.state.storage, principal.id)
        forget_principals(request)
    response.delete_cookie(TOKEN_COOKIE, httponly=True, secure=True, samesite="strict")


def _change_password(storage: Storage, user_id: int, body: PasswordChange) -> _Checked:
    with storage.db.session() as session:
        user = user_service.get_user(session, user_id)
        user_service.change_own_password(session, user, body.current_password, body.new_password)
        return _Checked(user.id, user.token_generation, disabled=False)


@router.post("/password", responses=_REFUSED)
async def change_password(
    body: PasswordChange, user: ViewerDep, request: Request, response: Response
) -> TokenRead:
    """Change your own password: revokes all your tokens and answers a new one (422 if the current is wrong)."""
    guard, address, storage = _guard(request), _address(request), request.app.state.storage
    try:
        await guard.check(user.name, address)
        checked = await guard.hashing(lambda: _change_password(storage, user.id, body))
    except LoginRefusedError as exc:
        raise _too_many(exc) from None
    except user_service.WrongPasswordError:
        await guard.failed(user.name, address)
        raise
    forget_principals(request)
    return _issue(request, response, checked)


@router.get("/me")
def me(user: ViewerDep) -> Me:
    """The logged-in user."""
    return Me(kind=user.kind, id=user.id, name=user.name, role=user.role)

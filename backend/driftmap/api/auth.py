"""Log in and out, and ask who you are."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, Response, status

from driftmap.api.deps import TOKEN_COOKIE, SessionDep, SettingsDep, ViewerDep
from driftmap.api.schemas_access import LoginRequest, Me, TokenRead
from driftmap.services import security
from driftmap.services import users as user_service

router = APIRouter(prefix="/auth", tags=["auth"])


@router.post("/login")
def login(body: LoginRequest, session: SessionDep, settings: SettingsDep, response: Response) -> TokenRead:
    """Exchange a user name and password for a bearer token (also set as an httponly cookie)."""
    user = user_service.authenticate(session, body.username, body.password)
    if user is None:
        raise HTTPException(
            status.HTTP_401_UNAUTHORIZED, "wrong user name or password", {"WWW-Authenticate": "Bearer"}
        )
    token = security.issue_token(security.secret_key(settings), user.id, settings.token_ttl_s)
    ttl = int(settings.token_ttl_s)
    response.set_cookie(TOKEN_COOKIE, token, max_age=ttl, httponly=True, secure=True, samesite="strict")
    return TokenRead(access_token=token, expires_in=ttl)


@router.post("/logout", status_code=status.HTTP_204_NO_CONTENT)
def logout(response: Response) -> None:
    """Forget the login cookie of this browser."""
    response.delete_cookie(TOKEN_COOKIE, httponly=True, secure=True, samesite="strict")


@router.get("/me")
def me(user: ViewerDep) -> Me:
    """The logged-in user."""
    return Me(kind=user.kind, id=user.id, name=user.name, role=user.role)

"""Passwords, login tokens and vehicle tokens.

- Passwords are hashed with argon2id (argon2-cffi defaults) and never stored in clear.
- A login token is ``<payload>.<signature>``: the payload is base64url JSON ``{"sub": user id, "exp": unix
  seconds, "gen": the user's token generation}``, the signature base64url HMAC-SHA256 of the payload under
  the server's secret key. A token is accepted only while ``gen`` equals the user's current
  ``token_generation``, so raising that revokes every token of the user.
- A vehicle token is ``dmv_<vehicle id>_<43 random base64url characters>`` (256 bits); only its SHA-256
  is stored, so a leaked database does not leak tokens.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import json
import os
import secrets
import time
from dataclasses import dataclass
from pathlib import Path

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError

from driftmap.config import Settings
from driftmap.formats.bounds import DB_INT_MAX

VEHICLE_TOKEN_PREFIX = "dmv_"
_hasher = PasswordHasher()


def hash_password(password: str) -> str:
    """The argon2id PHC string of ``password``."""
    return _hasher.hash(password)


def verify_password(password_hash: str, password: str) -> bool:
    """Whether ``password`` matches ``password_hash`` (False for a malformed hash)."""
    try:
        return _hasher.verify(password_hash, password)
    except (VerificationError, InvalidHashError):
        return False


# A fixed hash to verify against when the user does not exist, so timing does not reveal user names.
DUMMY_PASSWORD_HASH = hash_password("driftmap-no-such-user")


def secret_key(settings: Settings) -> bytes:
    """The token signing key: ``settings.secret_key``, or a random key created once under the data dir."""
    if settings.secret_key:
        return settings.secret_key.encode()
    path = Path(settings.data_dir) / "secret_key"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".secret_key-{os.getpid()}")
        tmp.write_text(secrets.token_urlsafe(48))
        tmp.chmod(0o600)
        try:
            os.link(tmp, path)  # atomic and refuses to overwrite: concurrent first starts agree on one key
        except FileExistsError:
            pass
        finally:
            tmp.unlink(missing_ok=True)
    return path.read_text().strip().encode()


def _b64(data: bytes) -> str:
    return base64.urlsafe_b64encode(data).rstrip(b"=").decode()


def _unb64(text: str) -> bytes:
    return base64.urlsafe_b64decode(text + "=" * (-len(text) % 4))


@dataclass(frozen=True)
class TokenClaims:
    """What a valid, unexpired login token says."""

    user_id: int
    generation: int
    """The user's ``token_generation`` when the token was issued."""


def issue_token(
    key: bytes, user_id: int, ttl_s: float, now_s: float | None = None, *, generation: int = 0
) -> str:
    """A signed login token for ``user_id`` (at token ``generation``) valid for ``ttl_s`` seconds."""
    now = time.time() if now_s is None else now_s
    claims = {"sub": user_id, "exp": int(now + ttl_s), "gen": generation}
    payload = _b64(json.dumps(claims, separators=(",", ":")).encode())
    signature = _b64(hmac.new(key, payload.encode(), hashlib.sha256).digest())
    return f"{payload}.{signature}"


def read_token(key: bytes, token: str, now_s: float | None = None) -> TokenClaims | None:
    """The claims of a valid, unexpired login token; None for anything else."""
    payload, _, signature = token.partition(".")
    if not payload or not signature:
        return None
    expected = _b64(hmac.new(key, payload.encode(), hashlib.sha256).digest())
    if not hmac.compare_digest(expected, signature):
        return None
    try:
        claims = json.loads(_unb64(payload))
        user_id, expires, generation = int(claims["sub"]), float(claims["exp"]), int(claims["gen"])
    except (ValueError, KeyError, TypeError, OverflowError):
        return None
    now = time.time() if now_s is None else now_s
    return TokenClaims(user_id, generation) if now < expires else None


def new_vehicle_token(vehicle_id: int) -> str:
    """A fresh random token for ``vehicle_id``."""
    return f"{VEHICLE_TOKEN_PREFIX}{vehicle_id}_{secrets.token_urlsafe(32)}"


def token_sha256(token: str) -> str:
    """What is stored of a vehicle token."""
    return hashlib.sha256(token.encode()).hexdigest()


def vehicle_id_of_token(token: str) -> int | None:
    """The vehicle id a vehicle token claims (still to be checked against its hash); None if not one."""
    if not token.startswith(VEHICLE_TOKEN_PREFIX):
        return None
    head, _, rest = token.removeprefix(VEHICLE_TOKEN_PREFIX).partition("_")
    if not (head.isdigit() and len(head) <= 10 and rest):
        return None
    return int(head) if int(head) <= DB_INT_MAX else None  # no row has a larger id

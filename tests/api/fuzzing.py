"""Fuzzing a running ``driftmap serve`` from its own OpenAPI document with schemathesis: the engine shared by
tests/api/test_fuzz_contract.py (a bounded run in ``make test``) and bench/fuzz_api.py (the same at scale).

Every operation of ``/api/openapi.json`` gets up to ``coverage`` of schemathesis's coverage cases (boundary
values: each bound and one past it, the largest integers, missing and empty values, wrong types, methods the
path does not take), then ``examples`` generated requests per generation mode (positive: valid by the schema;
negative: violating it somewhere), sent as one principal (an admin's bearer token, or none). Each answer is checked for:

* ``not_a_server_error``: no 5xx;
* ``status_code_conformance``: the status is one the operation documents;
* ``content_type_conformance``: the content type is the one documented for that status;
* ``response_schema_conformance``: the body matches the documented schema (dates with a zone included:
  ``format: date-time`` is checked);
* ``response_headers_conformance``: documented headers (``Location`` of a 202) are present and well-formed.

A failure never stops the run: each one is counted and the first of each (operation, check) is kept as a
readable report (the operation, the check's message, a curl command that repeats the request, the answer).

What the admin does not fuzz, because it would break the run itself rather than find a defect:

* ``POST /api/auth/logout`` revokes the run's own token (every later request would be 401);
* ``PATCH``/``DELETE /api/users/{user_id}`` on the admin's own id: any change of a user revokes that user's
  tokens; such a request is sent to a throwaway admin (``victim``) instead.

Everything else runs on a throwaway data directory, so deleting its sites, vehicles, drives, maps or users
loses nothing; the DELETE operations are fuzzed last, so the others still find what the data dir holds. The server runs without a job worker: accepted jobs (simulate, build, localise, import) stay
queued instead of loading the two cores.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import hypothesis
import jsonschema_rs
import requests
import schemathesis
from hypothesis import HealthCheck, Phase
from hypothesis.errors import Unsatisfiable
from schemathesis.checks import not_a_server_error
from schemathesis.core.failures import Failure, FailureGroup
from schemathesis.errors import InvalidSchema
from schemathesis.specs.openapi.checks import (
    content_type_conformance,
    response_headers_conformance,
    response_schema_conformance,
    status_code_conformance,
)

from tests.processes import start_server, stop

CHECKS = [
    not_a_server_error,
    status_code_conformance,
    content_type_conformance,
    response_schema_conformance,
    response_headers_conformance,
]
MODES = (schemathesis.GenerationMode.POSITIVE, schemathesis.GenerationMode.NEGATIVE)
ADMIN_PASSWORD = "fuzz-admin-password"
REQUEST_TIMEOUT_S = 60.0
START_DEADLINE_S = 120.0
SKIPPED_AS_ADMIN = {("POST", "/api/auth/logout"): "revokes the run's own token"}
"""Operations the admin does not fuzz, with the reason (see the module docstring)."""
OWN_USER_OPERATIONS = {("PATCH", "/api/users/{user_id}"), ("DELETE", "/api/users/{user_id}")}
"""Operations sent to the throwaway admin instead when they name the fuzzing admin's own id."""
REPORTS_KEPT = 40


@dataclass
class Principal:
    """Who sends the fuzzed requests: a name, its headers, and the ids it must not change."""

    name: str
    headers: dict[str, str]
    own_user_id: int | None = None
    victim_user_id: int | None = None

    def skips(self, method: str, path: str) -> bool:
        return self.own_user_id is not None and (method, path) in SKIPPED_AS_ADMIN


@dataclass
class Tally:
    """What a fuzzing run sent and found."""

    requests: int = 0
    by_status: Counter[int] = field(default_factory=Counter)
    server_errors: int = 0
    violations: int = 0
    """Answers that failed a check other than ``not_a_server_error``."""
    failures_by_check: Counter[str] = field(default_factory=Counter)
    reports: dict[tuple[str, str], str] = field(default_factory=dict)
    """The first report of each (operation, check), at most :data:`REPORTS_KEPT`."""
    skipped: list[str] = field(default_factory=list)
    elapsed_s: float = 0.0

    def summary(self) -> str:
        return (
            f"{self.requests} requests, {self.server_errors} server errors, {self.violations} schema "
            f"violations; statuses {dict(sorted(self.by_status.items()))}"
        )

    def report(self) -> str:
        """Every kept failure report, for an assertion message."""
        head = f"{self.summary()}; failures by check {dict(self.failures_by_check)}"
        return "\n\n".join([head, *self.reports.values()])


@dataclass
class FuzzServer:
    """A running throwaway ``driftmap serve``: its base URL, log and the fuzzing principals."""

    base: str
    log: Path
    process: subprocess.Popen[bytes]
    admin: Principal
    anonymous: Principal = field(default_factory=lambda: Principal("anonymous", {}))

    def schema(self) -> Any:
        """The server's own OpenAPI document, loaded by schemathesis."""
        return schemathesis.openapi.from_url(f"{self.base}/api/openapi.json")


def _add_admin(env: dict[str, str], name: str, password: str) -> None:
    added = subprocess.run(
        [sys.executable, "-m", "driftmap", "user", "add", name, "--role", "admin", "--password-stdin"],
        input=f"{password}\n".encode(),
        env=env,
        capture_output=True,
        check=False,
    )
    assert added.returncode == 0, added.stderr.decode()


@contextlib.contextmanager
def fuzz_server(env: dict[str, str], log: Path) -> Iterator[FuzzServer]:
    """``driftmap serve --no-worker`` in ``env`` (a throwaway data dir) with an admin, a throwaway admin and a
    vehicle for generated ids to find (with the data dir's first site, or a new one); stopped after."""
    _add_admin(env, "admin", ADMIN_PASSWORD)
    _add_admin(env, "victim", ADMIN_PASSWORD)
    process, base = start_server(env, log, "--no-worker", deadline_s=START_DEADLINE_S)
    try:
        login = requests.post(
            f"{base}/api/auth/login", json={"username": "admin", "password": ADMIN_PASSWORD}, timeout=30
        )
        assert login.status_code == 200, login.text
        headers = {"Authorization": f"Bearer {login.json()['access_token']}"}
        users = requests.get(f"{base}/api/users", headers=headers, timeout=30).json()
        ids = {user["username"]: user["id"] for user in users}
        sites = requests.get(f"{base}/api/sites", headers=headers, timeout=30).json()["items"]
        if not sites:
            site = requests.post(f"{base}/api/sites", json={"name": "fuzz"}, headers=headers, timeout=30)
            assert site.status_code == 201, site.text
            sites = [site.json()]
        vehicle = requests.post(
            f"{base}/api/vehicles",
            json={"name": "fuzz-vehicle", "site_id": sites[0]["id"]},
            headers=headers,
            timeout=30,
        )
        assert vehicle.status_code == 201, vehicle.text
        admin = Principal("admin", headers, own_user_id=ids["admin"], victim_user_id=ids["victim"])
        yield FuzzServer(base, log, process, admin)
    finally:
        stop(process)


def _protect(case: schemathesis.Case, principal: Principal) -> None:
    """Send a change of the fuzzing admin's own user to the throwaway admin instead."""
    if (case.method.upper(), case.path) not in OWN_USER_OPERATIONS or principal.own_user_id is None:
        return
    if str(case.path_parameters.get("user_id")) == str(principal.own_user_id):
        case.path_parameters["user_id"] = principal.victim_user_id


def _check_body(case: schemathesis.Case, response: schemathesis.Response, document: dict[str, Any]) -> None:
    """The body schema check, done here for the responses whose validator schemathesis cannot build: 4.32
    rewrites a tuple's ``prefixItems`` (``list[tuple[int, int]]``, valid OpenAPI 3.1) into a draft-4 ``items``
    array and then refuses that with its 2020-12 validator. The same check with jsonschema_rs directly."""
    documented = document["paths"][case.path][case.method.lower()]["responses"].get(str(response.status_code))
    media_type = _content_type(response).split(";")[0]
    schema = ((documented or {}).get("content", {}).get(media_type) or {}).get("schema")
    if schema is None or not media_type.endswith("json"):
        return
    validator = jsonschema_rs.Draft202012Validator(
        {**schema, "components": document["components"]}, validate_formats=True
    )
    errors = [
        f"{'/'.join(map(str, e.instance_path))}: {e.message}"
        for e in validator.iter_errors(json.loads(response.content))
    ]
    if errors:
        raise FailureGroup(
            [
                Failure(
                    operation=f"{case.method.upper()} {case.path}",
                    title="Response violates schema",
                    message="\n".join(errors[:5]),
                )
            ]
        )


def _content_type(response: schemathesis.Response) -> str:
    values = response.headers.get("content-type") or [""]
    return str(values[0])


def _response_text(response: schemathesis.Response) -> str:
    body = response.content[:600].decode("utf-8", "replace")
    return f"{response.status_code} {_content_type(response)}\n{body}"


def _record(
    tally: Tally, case: schemathesis.Case, failures: FailureGroup, response: schemathesis.Response
) -> None:
    label = f"{case.method.upper()} {case.path}"
    failed: list[Failure] = list(failures.exceptions)
    for failure in failed:
        name = type(failure).__name__
        tally.failures_by_check[name] += 1
        key = (label, name)
        if key in tally.reports or len(tally.reports) >= REPORTS_KEPT:
            continue
        curl = case.as_curl_command(headers=dict(response.request.headers))
        tally.reports[key] = (
            f"== {label} [{case.meta.generation.mode.value if case.meta else '?'}]: {failure.title}\n"
            f"{failure.message}\n-- request:\n{curl}\n-- response:\n{_response_text(response)}"
        )


@dataclass
class Sender:
    """Sends a generated request as ``principal``, checks the answer and counts both into ``tally``."""

    principal: Principal
    tally: Tally
    session: requests.Session
    base: str
    document: dict[str, Any]
    """The OpenAPI document, for the body check schemathesis cannot do (:func:`_check_body`)."""

    def __call__(self, case: schemathesis.Case) -> None:
        tally, headers = self.tally, self.principal.headers
        _protect(case, self.principal)
        try:
            response = case.call(
                base_url=self.base, session=self.session, headers=headers, timeout=REQUEST_TIMEOUT_S
            )
        except requests.RequestException as exc:  # a reset connection or a timeout counts as a server error
            tally.requests += 1
            tally.server_errors += 1
            tally.failures_by_check["TransportError"] += 1
            key = (f"{case.method.upper()} {case.path}", "TransportError")
            tally.reports.setdefault(key, f"== {key[0]}: {exc!r}\n{case.as_curl_command()}")
            return
        tally.requests += 1
        tally.by_status[response.status_code] += 1
        if response.status_code >= 500:
            tally.server_errors += 1
        try:
            try:
                case.validate_response(response, checks=CHECKS, headers=headers)
            except InvalidSchema:  # schemathesis could not build the body's validator: see _check_body
                case.validate_response(response, checks=CHECKS[:-2] + CHECKS[-1:], headers=headers)
                _check_body(case, response, self.document)
        except FailureGroup as failures:
            if response.status_code < 500:
                tally.violations += 1
            _record(tally, case, failures, response)


def cover_operation(operation: Any, cases: int, send: Sender) -> None:
    """Send at most ``cases`` of schemathesis's coverage cases of ``operation``: deterministic boundary
    values (each bound and one past it, the largest integers, empty and missing values, wrong types)."""
    schema = operation.schema
    generated = schema.iter_coverage_cases(
        operation,
        generation_modes=list(MODES),
        generation_config=schema.config.generation_for(operation=operation),
    )
    for case in itertools.islice(generated, cases):
        send(case)


def fuzz_operation(
    operation: Any, mode: schemathesis.GenerationMode, examples: int, send: Sender, *, seed: int | None = 0
) -> None:
    """Send ``examples`` requests of ``operation`` generated in ``mode`` (hypothesis, seeded by ``seed``)."""
    run = hypothesis.given(case=operation.as_strategy(generation_mode=mode))(send.__call__)
    run = hypothesis.settings(
        max_examples=examples,
        phases=[Phase.explicit, Phase.generate],
        deadline=None,
        database=None,
        derandomize=False,
        suppress_health_check=list(HealthCheck),
        report_multiple_bugs=False,
    )(run)
    if seed is not None:
        run = hypothesis.seed(seed)(run)
    try:
        run()
    except Unsatisfiable:  # nothing to negate (an operation without parameters or body)
        send.tally.skipped.append(f"{operation.label} [{mode.value}]: no such requests")


def fuzz(
    server: FuzzServer,
    principal: Principal,
    examples: int,
    *,
    coverage: int = 0,
    modes: tuple[schemathesis.GenerationMode, ...] = MODES,
    seed: int | None = 0,
    progress: Callable[[str, Tally], None] | None = None,
    tally: Tally | None = None,
) -> Tally:
    """Fuzz every operation of the server's OpenAPI document as ``principal`` (see the module docstring):
    up to ``coverage`` coverage cases, then ``examples`` generated requests per mode. Counts into ``tally``
    when given (one more round of a longer run), else into a new one."""
    tally = tally if tally is not None else Tally()
    started = time.monotonic()
    schema = server.schema()
    with requests.Session() as session:
        send = Sender(principal, tally, session, server.base, schema.raw_schema)
        operations = [result.ok() for result in schema.get_all_operations()]
        for operation in sorted(operations, key=lambda op: op.method.upper() == "DELETE"):
            method, path = operation.method.upper(), operation.path
            if principal.skips(method, path):
                tally.skipped.append(f"{method} {path}: {SKIPPED_AS_ADMIN[(method, path)]}")
                continue
            if coverage:
                cover_operation(operation, coverage, send)
            for mode in modes:
                fuzz_operation(operation, mode, examples, send, seed=seed)
            if progress is not None:
                progress(operation.label, tally)
    tally.elapsed_s += time.monotonic() - started
    return tally

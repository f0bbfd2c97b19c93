"""Upload size checks shared by the upload routes: early on ``Content-Length``, then while reading."""

from __future__ import annotations

from fastapi import Request, UploadFile

from driftmap.errors import PayloadTooLargeError

MULTIPART_SLACK_BYTES = 64 * 1024  # form boundaries and small fields around the files


def check_content_length(request: Request) -> None:
    """413 before the body is read when ``Content-Length`` exceeds the upload limit."""
    limit: int = request.app.state.settings.max_upload_bytes
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit + MULTIPART_SLACK_BYTES:
        raise PayloadTooLargeError(f"request body of {declared} bytes exceeds the {limit} byte upload limit")


def read_limited(file: UploadFile, max_bytes: int, filename: str) -> bytes:
    """The bytes of a (small) uploaded file; 413 when it is larger than ``max_bytes``."""
    data = file.file.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise PayloadTooLargeError(f"larger than the {max_bytes} byte upload limit", file=filename)
    return data

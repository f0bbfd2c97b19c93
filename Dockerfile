# syntax=docker/dockerfile:1
# driftmap in one image: the API (`driftmap serve`), the job workers (`driftmap worker`) and the CLI.
# Stage 1 builds the browser UI with Node; stage 2 installs the Python package beside the built UI.

FROM node:20-bookworm-slim AS frontend
WORKDIR /src/frontend
COPY frontend/package.json frontend/package-lock.json ./
RUN npm ci --no-audit --no-fund
COPY frontend/ ./
RUN npm run build

FROM python:3.11-slim-bookworm AS app
ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1
WORKDIR /app
# The server finds migrations/ and frontend/dist/ beside backend/ (three levels above driftmap/api/app.py),
# so the package is installed in place (editable) from /app rather than copied into site-packages.
COPY pyproject.toml README.md ./
COPY backend/ backend/
COPY migrations/ migrations/
RUN pip install -e .
COPY --from=frontend /src/frontend/dist/ frontend/dist/
RUN useradd --system --uid 10001 --home-dir /app --shell /usr/sbin/nologin driftmap \
    && mkdir -p /data \
    && chown driftmap:driftmap /data
USER driftmap
# The blob store (and, without DRIFTMAP_DATABASE_URL, the SQLite file): share it between api and workers.
ENV DRIFTMAP_DATA_DIR=/data
VOLUME ["/data"]
EXPOSE 8000
CMD ["driftmap", "serve", "--host", "0.0.0.0", "--port", "8000"]

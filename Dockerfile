# syntax=docker/dockerfile:1
# driftmap in one image: the API (`driftmap serve`), the job workers (`driftmap worker`) and the CLI.
# Stage 1 builds the browser UI with Node (22 LTS); stage 2 builds the wheel with the UI inside and installs it.

FROM node:22-bookworm-slim AS frontend
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
WORKDIR /src
# The package is installed from a wheel built beside the UI: the migrations and the built UI are its package
# data (driftmap/migrations, driftmap/ui), and every dependency is at the version of requirements.lock.
COPY pyproject.toml README.md requirements.lock ./
COPY backend/ backend/
COPY --from=frontend /src/frontend/dist/ frontend/dist/
RUN pip wheel --no-deps --wheel-dir /tmp/wheels . \
    && pip install -c requirements.lock /tmp/wheels/driftmap-*.whl \
    && rm -rf /tmp/wheels /src
WORKDIR /app
RUN useradd --system --uid 10001 --home-dir /app --shell /usr/sbin/nologin driftmap \
    && mkdir -p /data \
    && chown driftmap:driftmap /data
USER driftmap
# The blob store (and, without DRIFTMAP_DATABASE_URL, the SQLite file): share it between api and workers.
ENV DRIFTMAP_DATA_DIR=/data
VOLUME ["/data"]
EXPOSE 8000
CMD ["driftmap", "serve", "--host", "0.0.0.0", "--port", "8000"]

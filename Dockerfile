# motion-server container image.
#
#   docker build -t motion-server .
#   docker run --rm -p 5020:5020 -p 4840:4840 motion-server
#
# BASE_IMAGE: any Debian-like image with python3 (>= 3.11) and its venv module. The
# default is the official slim image; `make test-container` builds on a Debian base it
# bootstraps locally (no registry needed). docs/container.md documents the
# environment variables and the site-map / credentials conventions.
ARG BASE_IMAGE=python:3.11-slim

# --- build: a virtual environment with the runtime dependencies only (no test extra) ----
FROM ${BASE_IMAGE} AS build
# Optional, for builds behind a TLS-intercepting proxy or a PyPI mirror: a CA bundle path
# inside the build (bind-mount it) and an index URL. Empty means pip's own defaults.
ARG PIP_CERT=""
ARG PIP_INDEX_URL=""
WORKDIR /src
RUN python3 -m venv /opt/motion-server
# Dependencies first, in their own layer: it survives source changes.
COPY pyproject.toml ./
RUN set -eu; \
    [ -n "$PIP_CERT" ] || unset PIP_CERT; \
    [ -n "$PIP_INDEX_URL" ] || unset PIP_INDEX_URL; \
    python3 -c 'import tomllib; print("\n".join(tomllib.load(open("pyproject.toml", "rb"))["project"]["dependencies"]))' > requirements.txt; \
    /opt/motion-server/bin/pip install --no-cache-dir --disable-pip-version-check \
        -r requirements.txt
COPY README.md ./
COPY server server
COPY clients clients
RUN set -eu; \
    [ -n "$PIP_CERT" ] || unset PIP_CERT; \
    [ -n "$PIP_INDEX_URL" ] || unset PIP_INDEX_URL; \
    /opt/motion-server/bin/pip install --no-cache-dir --disable-pip-version-check \
        --no-deps .
COPY container/heartbeat.py /opt/motion-server/container/heartbeat.py

# --- runtime --------------------------------------------------------------------------
FROM ${BASE_IMAGE}
COPY --from=build /opt/motion-server /opt/motion-server
RUN groupadd --gid 10001 motion \
    && useradd --uid 10001 --gid motion --home-dir /nonexistent --no-create-home \
        --shell /usr/sbin/nologin motion \
    && mkdir -p /maps /var/lib/motion-server \
    && chown motion:motion /var/lib/motion-server
# Listen on every interface of the container (the site map default is 127.0.0.1), on the
# exposed ports whatever the site map says: publish them as you like (-p 15020:5020).
# The OPC UA pair takes effect once the site map has an [opcua] section.
ENV PATH=/opt/motion-server/bin:$PATH \
    PYTHONUNBUFFERED=1 \
    PYTHONDONTWRITEBYTECODE=1 \
    MOTION_SERVER_MODBUS_HOST=0.0.0.0 \
    MOTION_SERVER_MODBUS_PORT=5020 \
    MOTION_SERVER_OPCUA_HOST=0.0.0.0 \
    MOTION_SERVER_OPCUA_PORT=4840 \
    MOTION_SERVER_OPCUA_DATA_DIR=/var/lib/motion-server/opcua \
    MOTION_SERVER_DATA_DIR=/var/lib/motion-server
# Site map: the embedded demo map unless MOTION_SERVER_MAP names a file, e.g. one mounted
# at /maps/site.toml (-v ./maps:/maps:ro -e MOTION_SERVER_MAP=/maps/site.toml), or baked
# into a derived image (COPY site.toml /maps/site.toml + ENV MOTION_SERVER_MAP=...).
# OPC UA users: MOTION_SERVER_USERS_FILE names a users file (a mounted secret, by default
# /run/secrets/motion_server_users when present); see docs/container.md. Generated state (the OPC UA certificate) goes to /var/lib/motion-server.
WORKDIR /maps
USER motion
EXPOSE 5020 4840
# Healthy while the controller says Diagnostics.Ready over Modbus, its heartbeat (unless
# the clock is manual) keeps counting, and the OPC UA port (when the site map serves OPC
# UA) accepts connections. The first check exports the tag map (it loads the server's
# code: seconds on a busy machine) and keeps it for the next ones.
HEALTHCHECK --interval=15s --timeout=30s --start-period=60s --retries=3 \
    CMD ["python", "/opt/motion-server/container/heartbeat.py", "--quiet", \
        "--opcua-port", "auto", "--map-cache", "/tmp/motion-server-healthcheck.json"]
ENTRYPOINT ["motion-server"]
CMD ["run"]

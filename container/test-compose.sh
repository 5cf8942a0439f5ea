#!/usr/bin/env bash
# `make test-compose`: run the checked-in compose.yaml as the README does, with Debian's
# podman and podman-compose (as root), then start the image with no secret at all and log
# in over OPC UA with the admin it generated:
#
#   1. tools      install podman, podman-compose, runc, buildah, debootstrap when missing
#   2. engine     the image store of `make test-container` (its base image and layer cache)
#                 and an engine configuration of our own (see below)
#   3. compose    `podman-compose up --build --abort-on-container-exit --exit-code-from
#                 bench` on compose.yaml, no users secret prepared: exit status 0 (the bench
#                 waited for Diagnostics.Ready and saw the heartbeat count over the compose
#                 network), the server's own HEALTHCHECK passes, the first start created
#                 the admin in the data volume (logged where, never the password), and the
#                 server stops with the programmed stop and exit status 0
#   4. no secret  the image alone with a fresh data volume: healthy (its HEALTHCHECK),
#                 then an OPC UA client on the host logs in as admin with the password read
#                 from the volume (Basic256Sha256, SignAndEncrypt), may set the clock
#                 (admin), and a wrong password is refused
#
# The engine configuration (CONTAINERS_CONF, CONTAINERS_STORAGE_CONF; nothing under /etc
# changes): the image store of ours; runc as the OCI runtime (Debian bookworm's crun 1.8
# refuses a hybrid cgroup hierarchy with any controller on its cgroup v2 side: "cgroups in
# hybrid mode not supported, drop all controllers from cgroupv2"); container ulimits within
# this shell's hard limits (podman's defaults, nofile and nproc 1048576, need
# CAP_SYS_RESOURCE where they exceed them: "setrlimit RLIMIT_NOFILE: Operation not
# permitted"); container logs and events in files (no journald); networks of our own.
# Without systemd podman schedules no healthchecks (it says "unable to get systemd
# connection to add healthchecks"): this script runs them with `podman healthcheck run`.
#
# podman-compose 1.0.3 starts `depends_on` services in order without waiting for their
# health (the bench waits for readiness itself: heartbeat.py --wait), and after
# --abort-on-container-exit leaves the other containers running where docker compose
# stops them: here the script checks the server's HEALTHCHECK and then stops it as
# compose would (SIGTERM, 30 s grace).
#
# Environment: PYTHON (host interpreter with asyncua, default .venv/bin/python),
# STORAGE_DRIVER, DEBIAN_MIRROR (as for test-container.sh), KEEP_WORK=1.
set -euo pipefail
cd "$(dirname "$0")/.."
. container/lib.sh

PYTHON=${PYTHON:-.venv/bin/python}
PROJECT=motion-bench-$$
IMAGE=localhost/motion-server:local # compose.yaml's image: motion-server:local
SERVER=${PROJECT}_server_1
BENCH=${PROJECT}_bench_1
ALONE=$PROJECT-alone
ct_init test-compose

WORK=$(mktemp -d "${TMPDIR:-/tmp}/motion-server-compose.XXXXXX")
chmod 755 "$WORK"
COMPOSE_STARTED=""
cleanup() {
    local rc=$?
    if [ -n "$COMPOSE_STARTED" ]; then
        podman rm -f -t 5 "$ALONE" >/dev/null 2>&1 || true
        podman volume rm -f "$ALONE-data" >/dev/null 2>&1 || true
        podman-compose -p "$PROJECT" down -v >/dev/null 2>&1 || true
        podman network rm -f "${PROJECT}_default" >/dev/null 2>&1 || true
    fi
    if [ "${KEEP_WORK:-0}" = 1 ]; then
        echo "test-compose: scratch files kept in $WORK"
    else
        rm -rf "$WORK"
    fi
    exit "$rc"
}
trap cleanup EXIT
trap 'fail "line $LINENO: $BASH_COMMAND"' ERR
BUILDAH=(buildah)

# --- 1. tools ------------------------------------------------------------------------
step 1/4 "tools"
ct_tools podman:podman podman-compose:podman-compose runc:runc buildah:buildah \
    debootstrap:debootstrap \
    /usr/share/keyrings/debian-archive-keyring.gpg:debian-archive-keyring
info "$(podman --version), podman-compose $(podman-compose version 2>/dev/null |
    sed -n 's/^podman-compose[r]* version *//p' | head -1), $(runc --version | head -1)"
[ -x "$PYTHON" ] || fail "no host interpreter at $PYTHON (run through make, or set PYTHON)"

# --- 2. engine -----------------------------------------------------------------------
step 2/4 "engine"
ct_store
ct_base_image
nofile=$(ulimit -Hn)
nproc=$(ulimit -Hu)
if [ "$nofile" = unlimited ] || [ "$nofile" -gt 65536 ]; then nofile=65536; fi
if [ "$nproc" = unlimited ] || [ "$nproc" -gt 4096 ]; then nproc=4096; fi
cat >"$WORK/storage.conf" <<EOF
[storage]
driver = "$STORE_DRIVER"
graphroot = "$STORE_ROOT"
runroot = "$STORE_RUNROOT"
EOF
mkdir -p "$STORE_ROOT/networks"
cat >"$WORK/containers.conf" <<EOF
[containers]
default_ulimits = ["nofile=$nofile:$nofile", "nproc=$nproc:$nproc"]
log_driver = "k8s-file"

[engine]
runtime = "runc"
cgroup_manager = "cgroupfs"
events_logger = "file"

[network]
network_config_dir = "$STORE_ROOT/networks"
EOF
export CONTAINERS_CONF="$WORK/containers.conf" CONTAINERS_STORAGE_CONF="$WORK/storage.conf"
info "runtime runc, ulimits nofile=$nofile nproc=$nproc, store $STORE_DRIVER $STORE_ROOT"
ct_pip_settings
free_port() {
    "$PYTHON" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

# --- 3. compose ----------------------------------------------------------------------
step 3/4 "compose.yaml: server + bench"
# the build as compose makes it, on the local base, with the host's CA bundle and index
build_opts="--isolation chroot --format docker --layers"
build_args=()
if [ -n "$CA" ]; then
    build_opts+=" --volume $CA:$BUILD_CA:ro"
    build_args+=(--build-arg "PIP_CERT=$BUILD_CA")
fi
[ -z "$INDEX" ] || build_args+=(--build-arg "PIP_INDEX_URL=$INDEX")
MODBUS_PORT=$(free_port)
OPCUA_PORT=$(free_port)
export BASE_IMAGE MODBUS_PORT OPCUA_PORT
unset USERS_FILE MOTION_SERVER_MAP CLOCK
COMPOSE_STARTED=1
rc=0
timeout 900 podman-compose -p "$PROJECT" --podman-build-args "$build_opts" \
    up --build "${build_args[@]}" --abort-on-container-exit --exit-code-from bench \
    >"$WORK/compose.log" 2>&1 || rc=$?
podman logs "$SERVER" >"$WORK/server.log" 2>&1 || true
podman logs "$BENCH" >"$WORK/bench.log" 2>&1 || true
if [ "$rc" != 0 ]; then
    tail -40 "$WORK/compose.log" >&2
    fail "compose up: exit status $rc (compose log above)"
fi
grep -q '^healthy: Diagnostics.Heartbeat [0-9]* -> [0-9]* at server:5020, OPC UA port 4840 listening$' \
    "$WORK/bench.log" ||
    fail "the bench did not report a counting heartbeat: $(cat "$WORK/bench.log")"
info "bench: $(grep -m1 '^healthy' "$WORK/bench.log"), exit status 0"
info "built $IMAGE ($(podman images --format '{{.Size}}' "$IMAGE" | head -1))"

running=$(podman inspect --format '{{.State.Running}}' "$SERVER")
[ "$running" = true ] || fail "the server is not running after the bench ended (running: $running)"
out=$(podman healthcheck run "$SERVER" 2>&1) || fail "the server's HEALTHCHECK: $out"
info "server HEALTHCHECK: ${out:-healthy}"

volume=$(podman volume inspect --format '{{.Mountpoint}}' "${PROJECT}_motion-data")
password_file="$volume/opcua/admin-password"
[ -f "$password_file" ] || fail "no generated admin password in the data volume ($password_file)"
mode=$(stat -c '%a %u' "$password_file")
[ "$mode" = "600 10001" ] || fail "admin-password: mode and owner '$mode', not '600 10001'"
grep -q "created user admin (role admin); its password is in /var/lib/motion-server/opcua/admin-password" \
    "$WORK/server.log" || fail "no log line naming the password file: $(grep -i user "$WORK/server.log")"
if grep -qF "$(cat "$password_file")" "$WORK/server.log" "$WORK/compose.log"; then
    fail "the password appears in a log"
fi
info "first start: admin created in the data volume (mode 600, uid 10001), logged where only"

podman stop -t 30 "$SERVER" >/dev/null
podman logs "$SERVER" >"$WORK/server.log" 2>&1 || true
code=$(podman inspect --format '{{.State.ExitCode}}' "$SERVER")
[ "$code" = 0 ] || fail "the server exited with status $code: $(tail -5 "$WORK/server.log")"
grep -q 'programmed stop complete' "$WORK/server.log" || fail "no programmed stop on SIGTERM"
grep -q 'motion_server.supervisor: stopped' "$WORK/server.log" || fail "no clean stop"
info "stopped: $(grep -m1 'programmed stop complete' "$WORK/server.log" | cut -d' ' -f5-), exit 0"
podman-compose -p "$PROJECT" down -v >/dev/null 2>&1 || fail "compose down"
podman network rm -f "${PROJECT}_default" >/dev/null 2>&1 || true

# --- 4. the image with no secret -----------------------------------------------------
step 4/4 "the image with no secret: log in as the generated admin"
OPCUA_PORT=$(free_port)
podman volume create "$ALONE-data" >/dev/null
podman run -d --name "$ALONE" -v "$ALONE-data:/var/lib/motion-server" \
    -p "127.0.0.1:$OPCUA_PORT:4840" "$IMAGE" >/dev/null 2>"$WORK/run.err" ||
    fail "podman run: $(cat "$WORK/run.err")"
healthy=""
for _ in $(seq 1 60); do
    if podman healthcheck run "$ALONE" >/dev/null 2>&1; then
        healthy=1
        break
    fi
    [ "$(podman inspect --format '{{.State.Running}}' "$ALONE")" = true ] || break
    sleep 2
done
podman logs "$ALONE" >"$WORK/alone.log" 2>&1 || true
[ -n "$healthy" ] || fail "not healthy within 120 s: $(tail -5 "$WORK/alone.log")"
# healthy: the controller runs and both ports listen
grep -q "OPC UA on opc.tcp://" "$WORK/alone.log" || fail "healthy, but OPC UA does not listen"
volume=$(podman volume inspect --format '{{.Mountpoint}}' "$ALONE-data")
password=$(cat "$volume/opcua/admin-password")
[ -n "$password" ] || fail "empty admin password file"
out=$("$PYTHON" - "opc.tcp://127.0.0.1:$OPCUA_PORT/" "$password" "$WORK" <<'EOF'
import asyncio, logging, sys
from pathlib import Path

from asyncua import Client, ua
from asyncua.crypto.security_policies import SecurityPolicyBasic256Sha256

endpoint, password, work = sys.argv[1], sys.argv[2], Path(sys.argv[3])
logging.getLogger("asyncua").setLevel(logging.CRITICAL)  # the refusal is reported below


async def login(secret: str) -> str:
    client = Client(endpoint, timeout=10)
    client.application_uri = "urn:motion-server:test-compose"
    cert, key = await client.setup_self_signed_certificate(
        work / "client-key.pem", work / "client-cert.der"
    )
    await client.set_security(
        SecurityPolicyBasic256Sha256, str(cert), str(key),
        mode=ua.MessageSecurityMode.SignAndEncrypt,
    )
    client.set_user("admin")
    client.set_password(secret)
    try:
        async with client:
            ns = await client.get_namespace_index("urn:motion-server:demo")
            node = client.get_node(ua.NodeId("Clock.StepCycles", ns))
            dv = ua.DataValue(ua.Variant(7, ua.VariantType.UInt32))
            status = await client.uaclient.write_attributes([node.nodeid], [dv])
            return f"write Clock.StepCycles: {status[0].name}"
    except ua.UaStatusCodeError as exc:
        return f"refused: {type(exc).__name__}"


right = asyncio.run(login(password))
wrong = asyncio.run(login(password + "x"))
print(f"{right}; wrong password {wrong}")
EOF
) || fail "OPC UA login: $out"
[ "$out" = "write Clock.StepCycles: Good; wrong password refused: BadUserAccessDenied" ] ||
    fail "OPC UA login as the generated admin: $out"
info "OPC UA as admin: $out"
podman stop -t 30 "$ALONE" >/dev/null
code=$(podman inspect --format '{{.State.ExitCode}}' "$ALONE")
[ "$code" = 0 ] || fail "the server exited with status $code"

printf '\ntest-compose: OK (%ds)\n' $((SECONDS - T0))

#!/usr/bin/env bash
# `make test-container`: build the Dockerfile and smoke-test the image without a Docker
# engine or an image registry, using Debian's buildah and debootstrap (as root):
#
#   1. tools      install buildah and debootstrap when missing (apt-get)
#   2. base       bootstrap a minimal Debian with python3 + python3-venv and commit it as a
#                 local image; cached in the image store under a tag keyed on its recipe
#   3. build      the Dockerfile with BASE_IMAGE = that base (chroot isolation), pip
#                 trusting the host's CA bundle and using the host's index, if it has one
#   4. image      non-root user, exposed ports, healthcheck, runtime dependencies only,
#                 `motion-server check` on the embedded and on a mounted site map
#   5. run        `motion-server run` in the image: status line, the heartbeat read twice
#                 over Modbus from the host on 127.0.0.1 (it must count ~250 cycles in
#                 0.5 s), the image's own HEALTHCHECK command, a jog started over Modbus,
#                 then SIGTERM -> the programmed stop of the jog, exit status 0
#
# Environment: PYTHON (host interpreter with pymodbus, default .venv/bin/python),
# DEBIAN_MIRROR (default: the host's apt source for the suite, else deb.debian.org),
# STORAGE_DRIVER (overlay or vfs; default overlay where it works, else vfs; each has an
# image store of its own under /var/lib/containers/motion-server-<driver>),
# KEEP_WORK=1 (keep the scratch directory for inspection).
set -euo pipefail
cd "$(dirname "$0")/.."
. container/lib.sh

PYTHON=${PYTHON:-.venv/bin/python}
IMAGE=localhost/motion-server:test
ct_init test-container

WORK=$(mktemp -d "${TMPDIR:-/tmp}/motion-server-container.XXXXXX")
CONTAINER=""
SERVER_PID=""
RUNNER_PID=""
cleanup() {
    local rc=$?
    if [ -n "$SERVER_PID" ] && kill -0 "$SERVER_PID" 2>/dev/null; then
        kill -TERM "$SERVER_PID" 2>/dev/null || true
    fi
    if [ -n "$RUNNER_PID" ]; then
        wait "$RUNNER_PID" 2>/dev/null || true
    fi
    if [ -n "$CONTAINER" ]; then
        "${BUILDAH[@]}" rm "$CONTAINER" >/dev/null 2>&1 || true
    fi
    if [ "${KEEP_WORK:-0}" = 1 ]; then
        echo "test-container: scratch files kept in $WORK"
    else
        rm -rf "$WORK"
    fi
    exit "$rc"
}
trap cleanup EXIT
trap 'fail "line $LINENO: $BASH_COMMAND"' ERR
BUILDAH=(buildah)

# --- 1. tools ------------------------------------------------------------------------
step 1/5 "tools"
ct_tools buildah:buildah debootstrap:debootstrap \
    /usr/share/keyrings/debian-archive-keyring.gpg:debian-archive-keyring
info "$(buildah --version), $(debootstrap --version)"
[ -x "$PYTHON" ] || fail "no host interpreter at $PYTHON (run through make, or set PYTHON)"
ct_store

# --- 2. base image -------------------------------------------------------------------
step 2/5 "base image"
ct_base_image

# --- 3. build ------------------------------------------------------------------------
step 3/5 "build the Dockerfile on $BASE_IMAGE"
ct_pip_settings
build_args=(--build-arg "BASE_IMAGE=$BASE_IMAGE")
[ -z "$CA" ] || build_args+=(--volume "$CA:$BUILD_CA:ro" --build-arg "PIP_CERT=$BUILD_CA")
[ -z "$INDEX" ] || build_args+=(--build-arg "PIP_INDEX_URL=$INDEX")
if ! "${BUILDAH[@]}" bud --isolation chroot --format docker --layers "${build_args[@]}" \
    -f Dockerfile -t "$IMAGE" . >"$WORK/build.log" 2>&1; then
    tail -30 "$WORK/build.log" >&2
    fail "image build (log above)"
fi
# Keep the layer cache of this build, drop what earlier builds left: name the build stage
# too (answered from the cache), then prune the unnamed images no named one builds on.
"${BUILDAH[@]}" bud --isolation chroot --format docker --layers "${build_args[@]}" \
    --target build -f Dockerfile -t "$IMAGE-build" . >>"$WORK/build.log" 2>&1 ||
    fail "naming the build stage"
"${BUILDAH[@]}" rmi --prune >/dev/null 2>&1 || true
info "built $IMAGE ($("${BUILDAH[@]}" images --format '{{.Size}}' "$IMAGE"))"

# --- 4. image checks -----------------------------------------------------------------
step 4/5 "image checks"
cfg() { "${BUILDAH[@]}" inspect --type image --format "$1" "$IMAGE"; }
user=$(cfg '{{.Docker.Config.User}}')
[ -n "$user" ] && [ "$user" != root ] && [ "$user" != 0 ] || fail "image user is '$user'"
ports=$(cfg '{{range $p, $_ := .Docker.Config.ExposedPorts}}{{$p}} {{end}}')
for p in 5020/tcp 4840/tcp; do
    [[ " $ports " == *" $p "* ]] || fail "port $p not exposed (exposed: $ports)"
done
health=$(cfg '{{.Docker.Config.Healthcheck}}')
[[ "$health" == *heartbeat.py* ]] || fail "no heartbeat HEALTHCHECK (got: $health)"
info "user $user, exposes $ports, healthcheck $health"

CONTAINER=$("${BUILDAH[@]}" from --name "motion-server-test-$$" "$IMAGE")
in_image() { "${BUILDAH[@]}" run "$@"; }
uid=$(in_image "$CONTAINER" -- id -u)
[ "$uid" != 0 ] || fail "processes in the image run as root"
if in_image "$CONTAINER" -- python -c 'import pytest' >/dev/null 2>&1; then
    fail "test dependencies (pytest) are installed in the image"
fi
out=$(in_image "$CONTAINER" -- motion-server check) || fail "motion-server check: $out"
[[ "$out" == "<embedded demo.toml>: ok: "* ]] || fail "motion-server check said: $out"
in_image "$CONTAINER" -- sh -c 'touch /var/lib/motion-server/probe && rm /var/lib/motion-server/probe' ||
    fail "/var/lib/motion-server is not writable by the image user"
info "uid $uid, data directory writable, no test extra; $out"

mkdir -p "$WORK/maps"
cat >"$WORK/maps/site.toml" <<'EOF'
[[groups]]
name = "Bench"
axes = ["Conveyor", "Knife"]

[[axes]]
name = "Conveyor"
type = "virtual"

[[axes]]
name = "Knife"
type = "servo"
EOF
printf '[[axes]]\nname = "Bad"\nmax_velocity = -1\n' >"$WORK/maps/bad.toml"
chmod -R a+rX "$WORK"
out=$(in_image --volume "$WORK/maps:/maps:ro" --env MOTION_SERVER_MAP=/maps/site.toml \
    "$CONTAINER" -- motion-server check) || fail "mounted site map: $out"
[[ "$out" == "/maps/site.toml: ok: 2 axes, 1 groups"* ]] || fail "mounted site map: $out"
info "$out"
if out=$(in_image --volume "$WORK/maps:/maps:ro" --env MOTION_SERVER_MAP=/maps/bad.toml \
    "$CONTAINER" -- motion-server check 2>&1); then
    fail "a bad site map passed the check"
fi
[[ "$out" == *"/maps/bad.toml:3: axes.0.max_velocity"* ]] || fail "bad map error: $out"
info "bad map rejected: $(grep -m1 'bad.toml:3' <<<"$out")"

# --- 5. run --------------------------------------------------------------------------
step 5/5 "run the server in the image"
free_port() {
    "$PYTHON" -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}
# chroot isolation shares the host's network: free ports of the host for both protocols
PORT=$(free_port)
OPCUA_PORT=$(free_port)
LOG="$WORK/server.log"
in_image --env MOTION_SERVER_MODBUS_PORT="$PORT" --env MOTION_SERVER_OPCUA_PORT="$OPCUA_PORT" \
    --env MOTION_SERVER_CONTROLLER_STATUS_LOG_INTERVAL=1 \
    "$CONTAINER" -- motion-server run >"$LOG" 2>&1 &
RUNNER_PID=$!
# chroot isolation shares the host's PID and network namespaces; buildah run does not
# forward signals, so the server process gets them directly.
descendants() {
    local child
    for child in $(pgrep -P "$1"); do
        echo "$child"
        descendants "$child"
    done
}
for _ in $(seq 1 100); do
    for p in $(descendants "$RUNNER_PID"); do
        if [ "$(ps -o comm= -p "$p" 2>/dev/null)" = motion-server ]; then
            SERVER_PID=$p
        fi
    done
    [ -n "$SERVER_PID" ] && break
    sleep 0.2
done
[ -n "$SERVER_PID" ] || {
    cat "$LOG" >&2
    fail "the server process did not start"
}
wait_for() { # pattern, seconds
    local i
    for i in $(seq 1 $(($2 * 5))); do
        grep -q "$1" "$LOG" && return 0
        kill -0 "$RUNNER_PID" 2>/dev/null || break
        sleep 0.2
    done
    cat "$LOG" >&2
    fail "no '$1' in the server log within $2 s"
}
wait_for ' cycle [0-9]* t=' 30
wait_for "OPC UA on opc.tcp://[^ ]*:$OPCUA_PORT/" 120 # after Modbus: its address space first
info "pid $SERVER_PID, Modbus port $PORT: $(grep -m1 ' cycle [0-9]* t=' "$LOG" | cut -d' ' -f5-9)"

in_image "$CONTAINER" -- motion-server map --format json >"$WORK/map.json" ||
    fail "motion-server map --format json in the image"
# Twice from the host, 0.5 s apart: at the demo map's 2 ms period the heartbeat counts
# 0.5 / 0.002 = 250 cycles in between (realtime clock; accept half to one and a half).
out=$("$PYTHON" container/heartbeat.py --host 127.0.0.1 --port "$PORT" \
    --map-json "$WORK/map.json" --interval 0.5 --require-increase) ||
    fail "heartbeat read from the host: $out"
counted=$(sed -E 's/.* ([0-9]+) -> ([0-9]+) .*/\2 - \1/' <<<"$out")
counted=$((counted))
((counted >= 125 && counted <= 375)) || fail "heartbeat counted $counted cycles in 0.5 s, not ~250"
info "from the host: $out ($counted cycles, 250 expected)"
# the image's HEALTHCHECK command, as the engine would run it inside the container
out=$(in_image --env MOTION_SERVER_MODBUS_PORT="$PORT" --env MOTION_SERVER_OPCUA_PORT="$OPCUA_PORT" \
    "$CONTAINER" -- \
    $(cfg '{{range $i, $a := .Docker.Config.Healthcheck.Test}}{{if $i}}{{$a}} {{end}}{{end}}')) ||
    fail "the image's healthcheck: $out"
info "HEALTHCHECK in the image: exit 0 ${out:-(quiet)}"

# Jog the master so that SIGTERM has motion to stop: MC_Power_1 powers Axis1, MAJ_1 jogs it
# at 100 mm/s. Its programmed stop is a fast stop at its maximum deceleration, 5000 mm/s²
# in the demo map: 100 / 5000 = 0.020 s = 10 cycles of 2 ms.
out=$("$PYTHON" - "$WORK/map.json" "$PORT" <<'EOF'
import sys, time
sys.path.insert(0, "container")
import heartbeat as hb

with hb.Reader(hb.load_map(sys.argv[1]), "127.0.0.1", int(sys.argv[2]), 3.0) as r:
    r.write("MC_Power_1.Axis", 1)
    r.write("MC_Power_1.Enable", 1)
    for name, value in [("Axis", 1), ("Direction", 0), ("Speed", 100.0), ("SpeedUnits", 0),
                        ("AccelRate", 5000.0), ("AccelUnits", 0), ("DecelRate", 5000.0),
                        ("DecelUnits", 0), ("Profile", 0)]:
        r.write(f"MAJ_1.{name}", value)
    r.write("MAJ_1.Execute", 1)
    time.sleep(0.3)
    print(" ".join(f"{n}={r.read(r.tag(n))}" for n in
                   ("MAJ_1.DN", "MAJ_1.ER", "MAJ_1.ERR", "MAJ_1.IP", "Axis1.CommandVelocity")))
EOF
) || fail "jog over Modbus: $out"
[ "$out" = "MAJ_1.DN=1 MAJ_1.ER=0 MAJ_1.ERR=0 MAJ_1.IP=1 Axis1.CommandVelocity=100.0" ] ||
    fail "jog over Modbus: $out"
info "jog: $out"

kill -TERM "$SERVER_PID"
rc=0
wait "$RUNNER_PID" || rc=$?
RUNNER_PID=""
SERVER_PID=""
[ "$rc" = 0 ] || {
    cat "$LOG" >&2
    fail "the server exited with status $rc after SIGTERM"
}
grep -q 'programmed stop complete after 10 cycles (0.020 s simulated)' "$LOG" ||
    fail "SIGTERM: no programmed stop of the jog in 10 cycles: $(grep 'programmed stop' "$LOG")"
grep -q 'motion_server.supervisor: stopped' "$LOG" || fail "no clean stop on SIGTERM"
info "SIGTERM: $(grep -m1 'programmed stop complete' "$LOG" | cut -d' ' -f5-)"

printf '\ntest-container: OK (%ds)\n' $((SECONDS - T0))

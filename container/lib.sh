# What `make test-container` and `make test-compose` share; sourced by both, run as root.
#
#   ct_tools CMD:PACKAGE...   install the Debian packages of the commands that are missing
#   ct_store                  the image store of our own (BUILDAH, STORE_DRIVER, STORE_ROOT,
#                             STORE_RUNROOT): overlay where it can mount, else vfs
#   ct_base_image             BASE_IMAGE: a minimal Debian with python3, bootstrapped from the
#                             host's apt mirror once and cached under a tag keyed on its recipe
#   ct_pip_settings           CA and INDEX: the host's pip CA bundle and index, for the build
#
# The caller sets PYTHON (host interpreter), WORK (scratch directory) and defines step,
# info and fail; ct_init defines them with the caller's name.

export BUILDAH_ISOLATION=chroot
BASE_REPO=localhost/motion-server-base
# The base recipe: change any of these and the cache key changes with them.
BASE_SUITE=bookworm
BASE_VARIANT=minbase
BASE_PACKAGES=python3,python3-venv,ca-certificates,netbase
BASE_RECIPE_VERSION=1
BUILD_CA=/run/motion-server-build/ca.crt # where the host CA bundle appears in the build

ct_init() { # name
    CT_NAME=$1
    T0=$SECONDS
    step() { printf '\n== [%s] %s (%ds)\n' "$1" "$2" $((SECONDS - T0)); }
    info() { printf '   %s\n' "$*"; }
    fail() {
        printf '%s: FAILED: %s\n' "$CT_NAME" "$*" >&2
        exit 1
    }
}

ct_tools() { # command:package ...
    [ "$(id -u)" = 0 ] || fail "needs root (the container tools run as root here)"
    local missing=() item
    for item in "$@"; do
        if [[ "$item" == /* ]]; then # a file the package provides
            [ -e "${item%%:*}" ] || missing+=("${item#*:}")
        else
            command -v "${item%%:*}" >/dev/null || missing+=("${item#*:}")
        fi
    done
    if [ ${#missing[@]} -gt 0 ]; then
        info "installing ${missing[*]} (apt-get)"
        DEBIAN_FRONTEND=noninteractive apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
    fi
}

# An image store of our own (images, layer cache), apart from anything else on the machine
# that uses buildah or podman: pruning it touches nothing but ours. overlay where it can
# mount, else vfs (copies instead of mounting layers: slower, works everywhere).
# STORAGE_DRIVER=overlay|vfs forces one.
ct_store() {
    _ct_store_of() { # driver
        STORE_DRIVER=$1
        STORE_ROOT=/var/lib/containers/motion-server-$1
        STORE_RUNROOT=/run/containers/motion-server-$1
        BUILDAH=(buildah --storage-driver "$1" --root "$STORE_ROOT" --runroot "$STORE_RUNROOT")
    }
    local probe
    case "${STORAGE_DRIVER:-auto}" in
    vfs | overlay) _ct_store_of "$STORAGE_DRIVER" ;;
    *)
        _ct_store_of overlay
        probe=$("${BUILDAH[@]}" from scratch 2>/dev/null) || probe=""
        if [ -z "$probe" ] || ! "${BUILDAH[@]}" mount "$probe" >/dev/null 2>&1; then
            info "overlay storage unusable here: using vfs"
            [ -z "$probe" ] || "${BUILDAH[@]}" rm "$probe" >/dev/null 2>&1 || true
            probe=""
            _ct_store_of vfs
        fi
        [ -z "$probe" ] || "${BUILDAH[@]}" rm "$probe" >/dev/null 2>&1 || true
        ;;
    esac
    unset STORAGE_DRIVER
    info "image store: ${BUILDAH[*]:1}"
}

_ct_debian_mirror() {
    # the URI the host's apt uses for "$BASE_SUITE" (one-line or deb822 sources)
    python3 - "$BASE_SUITE" <<'EOF'
import glob, re, sys
suite = sys.argv[1]
found = []
for path in ["/etc/apt/sources.list", *sorted(glob.glob("/etc/apt/sources.list.d/*"))]:
    try:
        text = open(path, encoding="utf-8").read()
    except OSError:
        continue
    if path.endswith(".list"):
        for line in text.splitlines():
            m = re.match(r"\s*deb\s+(?:\[[^\]]*\]\s+)?(\S+)\s+(\S+)", line)
            if m and m.group(2) == suite:
                found.append(m.group(1))
    elif path.endswith(".sources"):
        for para in re.split(r"\n\s*\n", text):
            fields = {}
            for line in para.splitlines():
                if ":" in line and not line.lstrip().startswith("#"):
                    k, v = line.split(":", 1)
                    fields[k.strip().lower()] = v.split()
            if "deb" in fields.get("types", []) and suite in fields.get("suites", []):
                found.extend(fields.get("uris", []))
print(next((u for u in found if u.startswith(("http://", "https://"))), ""))
EOF
}

ct_base_image() {
    local arch key mirror rootfs ctr old
    arch=$(dpkg --print-architecture 2>/dev/null || echo amd64)
    key=$(printf '%s\n' "$BASE_SUITE" "$BASE_VARIANT" "$BASE_PACKAGES" "$arch" \
        "$BASE_RECIPE_VERSION" | sha256sum | cut -c1-12)
    BASE_IMAGE="$BASE_REPO:$BASE_SUITE-$key"
    if "${BUILDAH[@]}" inspect --type image "$BASE_IMAGE" >/dev/null 2>&1; then
        info "cached: $BASE_IMAGE"
        return
    fi
    mirror=${DEBIAN_MIRROR:-$(_ct_debian_mirror || true)}
    mirror=${mirror:-http://deb.debian.org/debian}
    info "debootstrap --variant=$BASE_VARIANT $BASE_SUITE from $mirror (about a minute)"
    rootfs="$WORK/rootfs"
    if ! debootstrap --variant="$BASE_VARIANT" --include="$BASE_PACKAGES" --arch="$arch" \
        "$BASE_SUITE" "$rootfs" "$mirror" >"$WORK/debootstrap.log" 2>&1; then
        tail -20 "$WORK/debootstrap.log" >&2
        fail "debootstrap (log above)"
    fi
    rm -rf "$rootfs"/var/cache/apt/archives/*.deb "$rootfs"/var/lib/apt/lists/* \
        "$rootfs"/var/log/*.log "$rootfs"/var/cache/debconf/*-old
    # a tarball keeps owners and modes (buildah copy of a directory would make every file
    # root:root, e.g. /etc/shadow loses its shadow group)
    tar -C "$rootfs" --numeric-owner -cf "$WORK/rootfs.tar" .
    ctr=$("${BUILDAH[@]}" from scratch)
    "${BUILDAH[@]}" add "$ctr" "$WORK/rootfs.tar" / >/dev/null
    "${BUILDAH[@]}" config --env LANG=C.UTF-8 --cmd python3 \
        --label "org.opencontainers.image.description=Debian $BASE_SUITE $BASE_VARIANT + $BASE_PACKAGES" \
        "$ctr"
    "${BUILDAH[@]}" commit --quiet --rm "$ctr" "$BASE_IMAGE" >/dev/null
    rm -rf "$rootfs" "$WORK/rootfs.tar"
    # older recipes of the base are dead weight now
    for old in $("${BUILDAH[@]}" images --format '{{.Name}}:{{.Tag}}'); do
        if [[ "$old" == "$BASE_REPO:"* && "$old" != "$BASE_IMAGE" ]]; then
            "${BUILDAH[@]}" rmi "$old" >/dev/null 2>&1 || true
        fi
    done
    info "committed $BASE_IMAGE"
}

_ct_pip_setting() { # the host's pip setting: environment first, then pip's config files
    local env_name=$1 key=$2 value
    value=${!env_name:-}
    if [ -z "$value" ]; then
        value=$("$PYTHON" -m pip config get "$key" 2>/dev/null || true)
    fi
    printf '%s' "$value"
}

ct_pip_settings() {
    local candidate
    CA=$(_ct_pip_setting PIP_CERT global.cert)
    for candidate in "$CA" "${SSL_CERT_FILE:-}" /etc/ssl/certs/ca-certificates.crt; do
        if [ -n "$candidate" ] && [ -f "$candidate" ]; then
            CA=$candidate
            break
        fi
    done
    if [ -f "$CA" ]; then
        info "pip trusts the host CA bundle $CA"
    else
        CA=""
    fi
    INDEX=$(_ct_pip_setting PIP_INDEX_URL global.index-url)
    case "$INDEX" in
    http://* | https://*) info "pip index $INDEX" ;;
    *) # (file:// indexes of the host do not exist in the build)
        INDEX=""
        info "pip index: PyPI"
        ;;
    esac
}

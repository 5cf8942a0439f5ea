# Quick start: `make run` (demo server on the embedded site map), `make test` (whole suite).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test lint typecheck unit bench maps tools node-tools kube-tools clean \
	test-container test-compose

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/motion-server run $(MAP)

# only the source trees that exist yet (bench/ arrives with the benchmarks)
LINT_DIRS := $(wildcard server clients tests bench examples)

lint: $(STAMP)
	$(BIN)/ruff check $(LINT_DIRS)
	$(BIN)/ruff format --check $(LINT_DIRS)

typecheck: $(STAMP)
	$(BIN)/mypy

test: lint typecheck tools node-tools kube-tools
	$(BIN)/pytest -q

# mbpoll: the Modbus client that is not Python, for the interop tests; gcc: compiles the
# FMU's C host (tests/fmi/host.c); chromium: Debian's browser, which the pinned Playwright
# (pyproject [test]) drives in the web page's browser tests (Playwright never downloads a
# browser of its own here). Debian packages, installed when missing and we are root, as on
# a fresh CI machine.
tools:
	@command -v mbpoll >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
		&& (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mbpoll) \
		>/dev/null 2>&1 || echo "note: mbpoll not installed; its interop test will be skipped"; }
	@command -v gcc >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
		&& (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq gcc libc6-dev) \
		>/dev/null 2>&1 || echo "note: gcc not installed; the FMU's C host test will be skipped"; }
	@command -v chromium >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
		&& (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium) \
		>/dev/null 2>&1 || echo "note: chromium not installed; the web browser tests will be skipped"; }

# kubectl: renders the Kubernetes manifests offline (`kubectl kustomize`) for
# tests/deploy. When missing and we are root: the Kubernetes project's apt repository,
# pinned to a minor release (Debian bookworm's kubernetes-client is 1.20, whose kustomize
# is too old for these manifests). Without it the manifest tests are skipped, and say so.
KUBE_MINOR := v1.32
KUBE_REPO  := https://pkgs.k8s.io/core:/stable:/$(KUBE_MINOR)/deb/
KUBE_KEY   := /etc/apt/keyrings/kubernetes-$(KUBE_MINOR).asc
kube-tools:
	@command -v kubectl >/dev/null 2>&1 || command -v kustomize >/dev/null 2>&1 \
		|| { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null \
		&& (mkdir -p /etc/apt/keyrings && curl -fsSL -o $(KUBE_KEY) $(KUBE_REPO)Release.key \
		&& echo "deb [signed-by=$(KUBE_KEY)] $(KUBE_REPO) /" \
		> /etc/apt/sources.list.d/kubernetes-$(KUBE_MINOR).list && apt-get update -qq \
		&& DEBIAN_FRONTEND=noninteractive apt-get install -y -qq kubectl) >/dev/null 2>&1 \
		|| echo "note: kubectl not installed; the Kubernetes manifest tests will be skipped"; }

# node-opcua: the OPC UA client that is not Python, for the interop test. `npm ci` from the
# lock file when node_modules is missing or older than the lock (quiet; when it cannot run,
# the test is skipped and says why)
NODE_PROJECT := tests/interop/node_opcua
NODE_STAMP   := $(NODE_PROJECT)/node_modules/.package-lock.json

node-tools: $(NODE_STAMP)
	@true

$(NODE_STAMP): $(NODE_PROJECT)/package-lock.json
	@command -v npm >/dev/null 2>&1 && (cd $(NODE_PROJECT) && npm ci --no-audit --no-fund \
		--loglevel=error >/dev/null 2>&1) && touch $@ \
		|| echo "note: npm ci failed in $(NODE_PROJECT); the node-opcua interop test will be skipped"

# regenerate the checked-in exports of the demo map (a test compares them)
maps: $(STAMP)
	@for f in json csv md; do $(BIN)/motion-server map --format $$f -o maps/demo-map.$$f; done
	@$(BIN)/motion-server map --format nodeset -o maps/demo-nodeset.xml
	@$(BIN)/motion-server map --format kepware -o maps/demo-kepware.csv
	@$(BIN)/motion-server map --format ignition -o maps/demo-ignition.json
	@$(BIN)/motion-server map --format l5x -o maps/demo-logix.L5X

# Build the Dockerfile and smoke-test the image with buildah (as root; see container/).
test-container: $(STAMP)
	PYTHON=$(BIN)/python container/test-container.sh

# Run compose.yaml (server + bench) with podman-compose, then log in over OPC UA to the
# image started with no secret (as root; installs podman when missing; see container/).
test-compose: $(STAMP)
	PYTHON=$(BIN)/python container/test-compose.sh

bench: $(STAMP)
	@for b in bench/*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache $(NODE_PROJECT)/node_modules

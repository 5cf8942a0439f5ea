"""The live page end to end: Debian's chromium (Playwright) against a real motion-server.

One server for the module (manual clock, the demo map with three users, the web view on
an ephemeral port); every test starts from the controller as it was at start
(``reset``) and opens its own browser context (its own cookies). Time moves only when a
test steps the clock, so every figure below is exact:

- the demo map's MAJ_1 jogs Axis1 (a virtual axis, enabled by MSO_1 first: a jog of an
  axis whose servo is off is refused with ER and ERR 5, docs/semantics.md);
- a trend row is one scan cycle: after N single steps the page holds N consecutive
  ticks, and each row's position is the one Modbus reads at that tick;
- a trigger keeps ``pre`` rows before the crossing row, that row and ``post`` rows after.
"""

from __future__ import annotations

import hashlib
import http.server
import json
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.web_browser_support import SKIP_REASON, chromium

pytestmark = pytest.mark.skipif(SKIP_REASON is not None, reason=SKIP_REASON or "")

if SKIP_REASON is None:
    from motion_server.frontends.certificates import pem_copy, server_certificate
    from motion_server.testing import MotionServer
    from tests.web_support import USERS, users_map

ROLE_OF = {"viewer": "vera", "operator": "otto", "admin": "ada"}


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    work = tmp_path_factory.mktemp("web-browser")
    srv = MotionServer.start(work, users_map(work), opcua=False, web=True)
    try:
        srv.keep_initial_state()
        yield srv
    finally:
        srv.stop()


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with chromium() as b:
        yield b


@pytest.fixture
def srv(server: Any) -> Any:
    server.reset()
    return server


def origin(srv: Any) -> str:
    return srv.web_url.rstrip("/")


def open_page(browser: Any, srv: Any, role: str, record: list[str] | None = None) -> Any:
    context = browser.new_context(viewport={"width": 1280, "height": 900}, accept_downloads=True)
    page = context.new_page()
    page.set_default_timeout(15_000)
    if record is not None:
        page.on("request", lambda r: record.append(r.url))
        page.on("websocket", lambda ws: record.append(ws.url))
    page.goto(srv.web_url)
    user = ROLE_OF[role]
    page.fill("#login-user", user)
    page.fill("#login-password", USERS[user][0])
    page.click("#login-submit")
    page.wait_for_function("() => window.msView && msView.statusCount > 0")
    return page


def wait_layout(page: Any, srv: Any, channels: list[str]) -> None:
    """The trend set in effect (the server announces it with the first cycle after)."""
    for _ in range(50):
        srv.step(1)
        done = page.evaluate(
            "(want) => !!msView.layout && JSON.stringify(msView.layout.channels) === want",
            json.dumps(channels, separators=(",", ":")),
        )
        if done:
            return
        page.wait_for_timeout(50)
    raise AssertionError(f"trend layout {channels} never took effect")


def enable_axis1(srv: Any) -> None:
    out = srv.trigger("MSO_1")
    assert out.ok, out


def test_log_in_with_each_role(browser: Any, srv: Any) -> None:
    for role, user in ROLE_OF.items():
        page = open_page(browser, srv, role)
        assert page.inner_text("#who") == f"{user} ({role})"
        assert page.locator('tr[data-instruction="MAJ_1"] button.arm').is_visible() == (
            role != "viewer"
        )
        assert page.locator("#clock-step").is_visible() == (role == "admin")
        page.context.close()


def test_admin_steps_the_clock_from_the_page(browser: Any, srv: Any) -> None:
    page = open_page(browser, srv, "admin")
    before = srv.read("Clock.Cycle")
    page.fill("#step-cycles", "25")
    page.click("#clock-step")
    page.wait_for_function("() => document.getElementById('message').textContent.includes('step')")
    assert "clock step done" in page.inner_text("#message")
    assert srv.read("Clock.Cycle") == before + 25
    page.context.close()


def test_admin_saves_and_restores_a_snapshot_from_the_page(browser: Any, srv: Any) -> None:
    enable_axis1(srv)
    srv.trigger("MAJ_1")
    srv.step(50)
    page = open_page(browser, srv, "admin")
    page.fill("#snapshot-number", "7")
    page.click("#snapshot-save")
    page.wait_for_function("() => document.getElementById('message').textContent.includes('7')")
    assert page.inner_text("#message") == "snapshot 7: save done"
    saved = srv.read("Axis1.ActualPosition")
    srv.step(100)
    assert srv.read("Axis1.ActualPosition") != saved  # the jog went on
    page.click("#snapshot-restore")
    page.wait_for_function(
        "() => document.getElementById('message').textContent.includes('restore')"
    )
    assert page.inner_text("#message") == "snapshot 7: restore done"
    assert srv.read("Axis1.ActualPosition") == saved
    page.context.close()


def test_the_axis_table_follows_a_jog(browser: Any, srv: Any) -> None:
    enable_axis1(srv)
    page = open_page(browser, srv, "operator")
    srv.trigger("MAJ_1")
    cell = page.locator('[data-tag="Axis1.ActualPosition"]')
    seen = []
    for _ in range(3):
        srv.step(100)
        want = srv.read("Axis1.ActualPosition")
        # the table shows what Modbus reads, within a status period (20 Hz)
        page.wait_for_function(
            "(w) => document.querySelector('[data-tag=\"Axis1.ActualPosition\"]')"
            ".textContent === w",
            arg=f"{want:.4f}",
        )
        seen.append(float(cell.inner_text()))
    assert seen[0] > 0 and seen[0] < seen[1] < seen[2]  # it moves, one way
    assert page.get_attribute('[data-tag="MAJ_1.IP"]', "data-on") == "1"
    page.context.close()


def test_a_trend_draws_every_cycle_of_a_stepped_run(browser: Any, srv: Any) -> None:
    enable_axis1(srv)
    page = open_page(browser, srv, "viewer")
    channels = ["Axis1.ActualPosition", "Axis1.ActualVelocity"]
    wait_layout(page, srv, channels)
    srv.trigger("MAJ_1")
    page.click("#clear")
    canvas = page.locator("#chart canvas")
    first_hash = hashlib.sha256(canvas.screenshot()).hexdigest()
    modbus: dict[int, float] = {}
    for _ in range(60):
        srv.step(1)
        got = srv.read_many(["Clock.Cycle", "Axis1.ActualPosition"])
        modbus[int(got["Clock.Cycle"])] = float(got["Axis1.ActualPosition"])
    last = max(modbus)
    page.wait_for_function("(t) => msView.rows().length && msView.rows().at(-1)[0] >= t", arg=last)
    rows = page.evaluate("msView.rows()")
    ticks = [int(r[0]) for r in rows]
    assert ticks == list(range(ticks[0], last + 1))  # every cycle, none twice, none missing
    assert set(modbus) <= set(ticks)
    assert page.evaluate("[msView.gaps, msView.gapTicks]") == [0, 0]
    # the CSV the button downloads: the positions Modbus read for the same ticks, exactly
    with page.expect_download() as dl:
        page.click("#csv-all")
    lines = Path(dl.value.path()).read_text().splitlines()
    assert lines[0] == "tick," + ",".join(channels)
    csv = {int(t): float(p) for t, p, _ in (line.split(",") for line in lines[1:])}
    assert {t: csv[t] for t in modbus} == modbus
    assert modbus[last] > 0  # the jog moved
    # and the chart shows it: the canvas changed
    page.wait_for_timeout(100)
    assert hashlib.sha256(canvas.screenshot()).hexdigest() != first_hash
    page.context.close()


def test_a_trigger_captures_pre_and_post_samples_around_a_dn_edge(browser: Any, srv: Any) -> None:
    enable_axis1(srv)
    page = open_page(browser, srv, "operator")
    page.fill("#channel-input", "MAJ_1.DN")
    page.click("#channel-add")
    wait_layout(page, srv, ["Axis1.ActualPosition", "Axis1.ActualVelocity", "MAJ_1.DN"])
    page.select_option("#trig-channel", "MAJ_1.DN")
    page.select_option("#trig-slope", "rising")
    page.fill("#trig-level", "0.5")
    page.fill("#trig-pre", "20")
    page.fill("#trig-post", "30")
    page.click("#trig-arm")
    srv.step(30)  # 30 cycles with DN low: the pre samples
    row = page.locator('tr[data-instruction="MAJ_1"]')
    row.locator("button.arm").click()
    row.locator("button.execute").click()
    page.wait_for_function("() => document.getElementById('message').textContent.includes('trig')")
    srv.step(40)
    page.wait_for_function("() => msView.trigger.state === 'triggered'")
    trig = page.evaluate("msView.trigger")
    ticks = [int(r[0]) for r in trig["rows"]]
    hit = int(trig["hitTick"])
    assert ticks == list(range(hit - 20, hit + 31))
    dn = [r[3] for r in trig["rows"]]
    assert dn == [0.0] * 20 + [1.0] * 31
    # the jog starts with DN: still at rest before the edge
    assert {r[2] for r in trig["rows"][:20]} == {0.0}
    assert page.get_attribute("#trig-state", "data-state") == "triggered"
    page.context.close()


def test_an_operator_triggers_maj_and_the_ip_bit_shows(browser: Any, srv: Any) -> None:
    enable_axis1(srv)
    page = open_page(browser, srv, "operator")
    row = page.locator('tr[data-instruction="MAJ_1"]')
    assert row.locator("button.execute").is_disabled()  # arm first
    row.locator('input[data-tag="MAJ_1.Speed"]').fill("20")
    row.locator("button.arm").click()
    row.locator("button.execute").click()
    page.wait_for_function("() => document.getElementById('message').textContent.includes('trig')")
    assert page.inner_text("#message") == "MAJ_1 triggered"
    srv.step(2)
    page.wait_for_function(
        "() => document.querySelector('[data-tag=\"MAJ_1.IP\"]').dataset.on === '1'"
    )
    got = srv.read_many(["MAJ_1.IP", "MAJ_1.Speed"])
    assert got == {"MAJ_1.IP": True, "MAJ_1.Speed": 20.0}
    page.context.close()


def test_a_viewer_cannot_trigger(browser: Any, srv: Any) -> None:
    enable_axis1(srv)
    page = open_page(browser, srv, "viewer")
    row = page.locator('tr[data-instruction="MAJ_1"]')
    assert row.locator("button.arm").is_hidden()
    assert row.locator('input[data-tag="MAJ_1.Speed"]').get_attribute("readonly") == ""
    # the page's own request, made anyway: refused by the server
    status = page.evaluate(
        """async () => (await fetch('/api/trigger', {method: 'POST',
             headers: {'Content-Type': 'application/json', 'X-CSRF-Token': msView.session.csrf},
             body: JSON.stringify({instruction: 'MAJ_1'})})).status"""
    )
    assert status == 403
    srv.step(5)
    assert srv.read_many(["MAJ_1.IP", "MAJ_1.Execute"]) == {
        "MAJ_1.IP": False,
        "MAJ_1.Execute": False,
    }
    page.context.close()


class _Blank(http.server.BaseHTTPRequestHandler):
    def do_GET(self) -> None:
        body = b"<!doctype html><title>elsewhere</title>"
        self.send_response(200)
        self.send_header("Content-Type", "text/html")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, *args: Any) -> None:
        pass


OPEN_WS = """(url) => new Promise((done) => { const ws = new WebSocket(url);
  ws.onopen = () => { done('open'); ws.close(); }; ws.onerror = () => done('refused'); })"""


def test_a_cross_origin_websocket_is_refused(browser: Any, srv: Any) -> None:
    """A page of another origin on the same host (another port: the same site, so the
    browser sends the session cookie along) is refused for its Origin alone."""
    other = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Blank)
    threading.Thread(target=other.serve_forever, daemon=True).start()
    try:
        page = open_page(browser, srv, "admin")
        ws_url = origin(srv).replace("http://", "ws://") + "/ws"
        assert page.evaluate(OPEN_WS, ws_url) == "open"  # from the page's own origin
        page.goto(f"http://127.0.0.1:{other.server_address[1]}/")
        assert page.evaluate(OPEN_WS, ws_url) == "refused"
        page.context.close()
    finally:
        other.shutdown()


def test_no_request_leaves_the_origin(browser: Any, srv: Any) -> None:
    urls: list[str] = []
    enable_axis1(srv)
    page = open_page(browser, srv, "admin", record=urls)
    problems: list[str] = []
    page.on("console", lambda m: problems.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: problems.append(str(e)))
    wait_layout(page, srv, ["Axis1.ActualPosition", "Axis1.ActualVelocity"])
    page.click("#clock-step")
    page.click("#csv-visible")
    srv.step(20)
    page.wait_for_timeout(200)
    here = origin(srv)
    ws_here = here.replace("http://", "ws://")
    assert f"{ws_here}/ws" in urls
    assert f"{here}/static/uPlot.iife.min.js" in urls
    mine = (here + "/", ws_here + "/", f"blob:{here}/")  # blob: the CSV made in the page
    outside = [u for u in urls if not u.startswith(mine)]
    assert outside == []
    page.set_viewport_size({"width": 900, "height": 700})  # the chart follows the window
    page.wait_for_timeout(100)
    # the server's CSP let everything the page does run: no violation, no script error
    assert problems == []
    page.context.close()


def test_the_page_over_https_uses_wss(browser: Any, tmp_path: Path) -> None:
    """With a certificate the page is served over HTTPS and its WebSocket is wss: on the
    same origin (the browser trusts the test's self-signed certificate only)."""
    found = server_certificate(tmp_path / "pki", "127.0.0.1", "web")
    cert, key = pem_copy(found.cert), found.key
    site = tmp_path / "tls.toml"
    site.write_text(
        users_map(tmp_path)
        .read_text("utf-8")
        .replace(
            "allow_anonymous = false",
            f'allow_anonymous = false\ncert_file = "{cert}"\nkey_file = "{key}"',
            1,
        ),
        "utf-8",
    )
    tls = MotionServer.start(tmp_path, site, opcua=False, web=True)
    try:
        assert tls.web_url.startswith("https://")
        urls: list[str] = []
        context = browser.new_context(ignore_https_errors=True)
        page = context.new_page()
        page.on("websocket", lambda ws: urls.append(ws.url))
        page.goto(tls.web_url)
        page.fill("#login-user", "ada")
        page.fill("#login-password", USERS["ada"][0])
        page.click("#login-submit")
        page.wait_for_function("() => window.msView && msView.statusCount > 0")
        assert urls == [tls.web_url.replace("https://", "wss://") + "ws"]
        assert page.inner_text("#link-state") == "online"
        context.close()
    finally:
        tls.stop()

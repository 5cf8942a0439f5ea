"""The live page's own logic in Debian's chromium, against a scripted contract stub.

The stub (tests/web_support.py) speaks docs/web.md § "Protocol" with frames the test
writes, so the numbers below are known before the page sees them: a capture keeps every
row it was sent, a gap is counted by the ticks missing between two rows, a trigger keeps
``pre`` rows before the crossing row, the row itself and ``post`` rows after it, and the
cursors' Δt is Δticks × the controller's period (2000 µs in the stub's model).
The end-to-end cases against the real server are in test_web_browser.py.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterator
from typing import Any

import pytest

from tests.web_browser_support import SKIP_REASON, STATIC, ContractStub, chromium, frame

CHANNELS = ["Axis1.ActualPosition", "Axis1.ActualVelocity"]


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    if SKIP_REASON is not None:
        pytest.skip(SKIP_REASON)
    with chromium() as b:
        yield b


@pytest.fixture
def stub() -> Iterator[ContractStub]:
    with ContractStub() as s:
        yield s


def open_page(browser: Any, stub: ContractStub, role: str) -> Any:
    """A fresh context (own cookies), logged in as ``role`` (password = role in the stub)."""
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    page = context.new_page()
    page.set_default_timeout(10_000)
    page.goto(stub.url)
    page.fill("#login-user", role)
    page.fill("#login-password", role)
    page.click("#login-submit")
    page.wait_for_function("() => window.msView && msView.layout && msView.layout.id >= 1")
    return page


def layout_id(page: Any) -> int:
    return int(page.evaluate("msView.layout.id"))


def wait_rows(page: Any, n: int) -> None:
    page.wait_for_function(f"() => msView.rows().length >= {n}")


def test_each_role_sees_its_controls(browser: Any, stub: ContractStub) -> None:
    seen = {}
    for role in ("viewer", "operator", "admin"):
        page = open_page(browser, stub, role)
        assert page.inner_text("#who") == f"{role} ({role})"
        seen[role] = (
            page.locator("#instr-table button.arm").is_visible(),
            page.locator("#admin").is_visible(),
            page.locator('#instr-table input[data-tag="MAJ_1.Speed"]').get_attribute("readonly"),
        )
        page.context.close()
    assert seen["viewer"] == (False, False, "")  # readonly attribute present
    assert seen["operator"] == (True, False, None)
    assert seen["admin"] == (True, True, None)


def test_a_wrong_password_says_so_and_stays_out(browser: Any, stub: ContractStub) -> None:
    page = browser.new_page()
    page.goto(stub.url)
    page.fill("#login-user", "operator")
    page.fill("#login-password", "not-it")
    page.click("#login-submit")
    page.wait_for_function("() => document.getElementById('login-error').textContent !== ''")
    assert "wrong password" in page.inner_text("#login-error")
    assert page.locator("#main").is_hidden()
    page.close()


def test_the_capture_keeps_every_row_and_counts_a_gap(browser: Any, stub: ContractStub) -> None:
    page = open_page(browser, stub, "viewer")
    lid = layout_id(page)
    first = [(t, t * 0.5, 1.0 / 3.0 + t) for t in range(1, 101)]
    after = [(t, t * 0.5, 1.0 / 3.0 + t) for t in range(131, 201)]  # ticks 101..130 missing
    stub.send(frame(lid, first))
    stub.send(frame(lid, after, gaps_before=30))
    wait_rows(page, 170)
    assert page.evaluate("[msView.gaps, msView.gapTicks]") == [1, 30]
    assert page.inner_text("#gap-ticks") == "30"
    rows = page.evaluate("msView.rows()")
    assert rows == [list(r) for r in first + after]
    # the plotted line breaks at the gap: one null between tick 100 and tick 131
    data = page.evaluate("msView.capture().plotData()")
    assert data[0][100] == pytest.approx(115.5) and data[1][100] is None
    assert len(data[0]) == 171
    # CSV: every row, full float64 precision, no row for the gap
    csv = page.evaluate("msView.csv('all')").splitlines()
    assert csv[0] == "tick," + ",".join(CHANNELS)
    assert len(csv) == 1 + 170
    assert csv[1] == f"1,0.5,{1.0 / 3.0 + 1!r}"
    page.context.close()


def test_a_frame_of_an_old_layout_is_not_mixed_in(browser: Any, stub: ContractStub) -> None:
    page = open_page(browser, stub, "viewer")
    lid = layout_id(page)
    stub.send(frame(lid + 7, [(1, 1.0, 2.0)]))
    stub.send(frame(lid, [(5, 5.0, 6.0)]))
    wait_rows(page, 1)
    assert page.evaluate("msView.rows()") == [[5, 5.0, 6.0]]
    page.context.close()


def test_a_trigger_keeps_pre_and_post_rows_around_a_dn_edge(
    browser: Any, stub: ContractStub
) -> None:
    page = open_page(browser, stub, "viewer")
    page.fill("#channel-input", "MAJ_1.DN")
    page.click("#channel-add")
    page.wait_for_function("() => msView.layout.channels.length === 3")
    lid = layout_id(page)
    page.select_option("#trig-channel", "MAJ_1.DN")
    page.fill("#trig-level", "0.5")
    page.fill("#trig-pre", "5")
    page.fill("#trig-post", "7")
    page.click("#trig-arm")
    assert page.get_attribute("#trig-state", "data-state") == "armed"
    # DN rises at tick 50 (0 up to 49, 1 from 50); nothing before the edge may fire it
    rows = [(t, float(t), 0.0, 1.0 if t >= 50 else 0.0) for t in range(1, 101)]
    stub.send(frame(lid, rows[:55]))  # tick 55: only 5 post rows yet
    wait_rows(page, 55)
    assert page.get_attribute("#trig-state", "data-state") == "filling"
    stub.send(frame(lid, rows[55:]))
    page.wait_for_function("() => msView.trigger.state === 'triggered'")
    trig = page.evaluate("msView.trigger")
    assert trig["hitTick"] == 50
    assert [r[0] for r in trig["rows"]] == list(range(45, 58))  # 5 pre, the edge, 7 post
    assert [r[3] for r in trig["rows"]] == [0.0] * 5 + [1.0] * 8
    # the exact bit-change marker of the trended DN
    assert {"tick": 50, "tag": "MAJ_1.DN", "on": True, "exact": True} in page.evaluate(
        "msView.markers"
    )
    # the CSV of the capture is the triggered rows
    assert len(page.evaluate("msView.csv('all')").splitlines()) == 1 + 13
    page.context.close()


def test_cursors_give_the_difference_and_the_time_between(browser: Any, stub: ContractStub) -> None:
    page = open_page(browser, stub, "viewer")
    lid = layout_id(page)
    stub.send(frame(lid, [(t, 2.0 * t, 100.0 - t) for t in range(1, 51)]))
    wait_rows(page, 50)
    page.evaluate("msView.setCursor('A', 10); msView.setCursor('B', 35)")
    page.wait_for_function("() => msView.cursors && msView.cursors.b === 35")
    cur = page.evaluate("msView.cursors")
    assert cur["dticks"] == 25
    assert cur["dms"] == pytest.approx(25 * 2000 / 1000)
    assert cur["channels"]["Axis1.ActualPosition"] == {"a": 20.0, "b": 70.0, "delta": 50.0}
    assert cur["channels"]["Axis1.ActualVelocity"]["delta"] == -25.0
    text = page.inner_text("#cursor-table")
    assert "Δ (25 ticks, 50 ms)" in text
    page.context.close()


def test_csv_of_the_visible_range_after_a_zoom(browser: Any, stub: ContractStub) -> None:
    page = open_page(browser, stub, "viewer")
    lid = layout_id(page)
    stub.send(frame(lid, [(t, float(t), 0.0) for t in range(1, 301)]))
    wait_rows(page, 300)
    page.evaluate("msView.zoom(100, 120)")
    page.wait_for_function("() => document.getElementById('run-stop').textContent === 'Run'")
    csv = page.evaluate("msView.csv('visible')").splitlines()
    assert [int(line.split(",")[0]) for line in csv[1:]] == list(range(100, 121))
    page.context.close()


def test_xy_view_draws_master_against_slave(browser: Any, stub: ContractStub) -> None:
    page = open_page(browser, stub, "viewer")
    lid = layout_id(page)
    stub.send(frame(lid, [(t, float(t), 0.5 * t) for t in range(1, 201)]))
    wait_rows(page, 200)
    page.select_option("#view-mode", "xy")
    page.wait_for_function(
        """() => { const c = document.getElementById('xy');
          const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
          for (let i = 3; i < d.length; i += 4) if (d[i]) return true; return false; }"""
    )
    assert page.locator("#chart").is_hidden()
    page.context.close()


def test_operator_arms_then_executes_and_viewer_has_no_command(
    browser: Any, stub: ContractStub
) -> None:
    page = open_page(browser, stub, "operator")
    row = page.locator('tr[data-instruction="MAJ_1"]')
    assert row.locator("button.execute").is_disabled()  # arm first
    row.locator('input[data-tag="MAJ_1.Speed"]').fill("12.5")
    row.locator("button.arm").click()
    row.locator("button.execute").click()
    page.wait_for_function("() => document.getElementById('message').textContent.includes('trig')")
    assert stub.calls[-2:] == [
        ("write", {"writes": {"MAJ_1.Speed": 12.5}}),
        ("trigger", {"instruction": "MAJ_1"}),
    ]
    page.context.close()
    viewer = open_page(browser, stub, "viewer")
    assert viewer.locator('tr[data-instruction="MAJ_1"] button.arm').is_hidden()
    viewer.context.close()


def test_status_values_land_in_the_tables_and_the_bar(browser: Any, stub: ContractStub) -> None:
    page = open_page(browser, stub, "viewer")
    stub.send(
        {
            "type": "status",
            "tick": 4242,
            "cycle_us": 2000,
            "overruns": 3,
            "clock": "manual",
            "frontends": {"modbus": "up", "web": "down"},
            "values": {"Axis2.ActualPosition": 12.5, "MAJ_1.IP": True, "MAJ_1.DN": False},
        }
    )
    page.wait_for_function("() => msView.status && msView.status.tick === 4242")
    assert page.inner_text('[data-tag="Axis2.ActualPosition"]') == "12.5000"
    assert page.get_attribute('[data-tag="MAJ_1.IP"]', "data-on") == "1"
    assert page.get_attribute('[data-tag="MAJ_1.DN"]', "data-on") == "0"
    assert page.inner_text("#overruns") == "3"
    assert page.get_attribute("#frontends .health:nth-child(2)", "data-ok") == "0"
    page.context.close()


def test_a_bit_change_seen_in_the_status_is_a_marker(browser: Any, stub: ContractStub) -> None:
    page = open_page(browser, stub, "viewer")
    status = {"type": "status", "cycle_us": 9.0, "overruns": 0, "clock": "MANUAL"}
    # the first message gives the state (IP already true): no change, no marker
    stub.send({**status, "tick": 100, "values": {"MAJ_1.IP": True, "MAJ_1.DN": False}})
    stub.send({**status, "tick": 120, "values": {"MAJ_1.IP": False}})
    stub.send({**status, "tick": 140, "values": {"MAJ_1.DN": True}})
    page.wait_for_function("() => msView.status && msView.status.tick === 140")
    assert page.evaluate("msView.markers") == [
        {"tick": 120, "tag": "MAJ_1.IP", "on": False, "exact": False},
        {"tick": 140, "tag": "MAJ_1.DN", "on": True, "exact": False},
    ]
    page.context.close()


def test_zoom_pan_and_a_cursor_with_the_mouse(browser: Any, stub: ContractStub) -> None:
    page = open_page(browser, stub, "viewer")
    lid = layout_id(page)
    stub.send(frame(lid, [(t, float(t), 0.0) for t in range(1, 1001)]))
    wait_rows(page, 1000)
    page.wait_for_function("() => msView.renders > 0")
    over = page.locator("#chart .u-over").bounding_box()
    assert over is not None
    y = over["y"] + over["height"] / 2
    # drag across the middle fifth of the plot: the chart stops following and zooms there
    page.mouse.move(over["x"] + over["width"] * 0.4, y)
    page.mouse.down()
    page.mouse.move(over["x"] + over["width"] * 0.6, y, steps=5)
    page.mouse.up()
    page.wait_for_function("() => document.getElementById('run-stop').textContent === 'Run'")
    ticks = [int(r.split(",")[0]) for r in page.evaluate("msView.csv('visible')").split()[1:]]
    lo, hi = ticks[0], ticks[-1]
    assert 350 < lo < 450 and 550 < hi < 650  # about 400..600 of ticks 1..1000
    # pan right by half the width
    page.click("#pan-right")
    page.wait_for_timeout(100)
    moved = [int(r.split(",")[0]) for r in page.evaluate("msView.csv('visible')").split()[1:]]
    assert abs((moved[0] - lo) - (hi - lo) / 2) <= 2
    # a click puts cursor A on the nearest row
    page.mouse.click(over["x"] + over["width"] / 2, y)
    page.wait_for_function("() => msView.cursors && msView.cursors.a !== null")
    a = page.evaluate("msView.cursors.a")
    assert moved[0] <= a <= moved[-1]
    assert page.evaluate("msView.cursors.channels['Axis1.ActualPosition'].a") == float(a)
    # Follow: back to the newest window
    page.click("#zoom-reset")
    page.wait_for_function("() => document.getElementById('run-stop').textContent === 'Stop'")
    page.context.close()


def test_a_long_range_is_drawn_as_an_envelope_that_keeps_every_peak(
    browser: Any, stub: ContractStub
) -> None:
    page = open_page(browser, stub, "viewer")
    lid = layout_id(page)
    n = 60_000
    rows = [(t, 1000.0 if t == 31_234 else float(t % 100), -2.0 if t == 7_777 else 0.0)
            for t in range(1, n + 1)]  # fmt: skip
    for k in range(0, n, 10_000):
        stub.send(frame(lid, rows[k : k + 10_000]))
    wait_rows(page, n)
    page.evaluate(f"msView.zoom(1, {n})")
    page.wait_for_function("() => msView.plotted && msView.plotted[0][0] === 1")
    x, pos, vel = page.evaluate("msView.plotted")
    width = page.evaluate("document.querySelector('#chart .uplot').clientWidth")
    assert len(x) <= 4 * max(400, width) + 2  # no more than ~4 points per pixel
    assert max(pos) == 1000.0 and min(pos) == 0.0  # the single-row spike is kept
    assert min(vel) == -2.0
    assert x == sorted(x) and x[-1] == n
    # the CSV still has every row
    assert len(page.evaluate("msView.csv('visible')").splitlines()) == 1 + n
    page.context.close()


def test_anonymous_viewers_may_still_log_in(browser: Any) -> None:
    with ContractStub(anonymous_role="viewer") as stub:
        page = browser.new_page()
        page.goto(stub.url)
        page.wait_for_function("() => window.msView && msView.session !== null")
        assert page.inner_text("#who") == "anonymous (viewer)"
        assert page.locator("#admin").is_hidden()
        page.click("#login-open")
        page.fill("#login-user", "admin")
        page.fill("#login-password", "admin")
        page.click("#login-submit")
        page.wait_for_function("() => msView.session.role === 'admin'")
        assert page.locator("#admin").is_visible()
        assert page.locator("#login").is_hidden()
        page.close()


def test_the_page_reconnects_and_asks_for_a_login_once_the_session_is_gone(
    browser: Any, stub: ContractStub
) -> None:
    page = open_page(browser, stub, "operator")
    first = layout_id(page)
    stub.drop()  # the socket closes; the session is still good: the page comes back
    page.wait_for_function(f"() => msView.layout.id > {first}")
    assert page.inner_text("#link-state") == "online"
    assert stub.layouts[-1] == CHANNELS  # the trend asked again
    stub.forget_sessions()
    stub.drop()  # and now the server forgot the session: log in again
    page.wait_for_function("() => !document.getElementById('login').hidden")
    assert page.inner_text("#login-error") == "the session ended: log in again"
    assert page.locator("#main").is_hidden()
    page.context.close()


def test_nothing_leaves_the_origin_and_the_csp_holds(browser: Any, stub: ContractStub) -> None:
    context = browser.new_context()
    page = context.new_page()
    urls: list[str] = []
    problems: list[str] = []
    page.on("request", lambda r: urls.append(r.url))
    page.on("websocket", lambda ws: urls.append(ws.url))
    page.on("console", lambda m: problems.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: problems.append(str(e)))
    page.goto(stub.url)
    page.fill("#login-user", "admin")
    page.fill("#login-password", "admin")
    page.click("#login-submit")
    page.wait_for_function("() => msView.layout && msView.layout.id >= 1")
    stub.send(frame(layout_id(page), [(t, float(t), 0.0) for t in range(1, 50)]))
    wait_rows(page, 49)
    origin = stub.url
    ws_origin = origin.replace("http://", "ws://")
    outside = [u for u in urls if not (u.startswith(origin + "/") or u.startswith(ws_origin))]
    assert outside == []
    assert f"{ws_origin}/ws" in urls
    # the page loads without a CSP violation or script error (the 401 before login is not
    # one); a violation would be logged as an error naming the Content Security Policy
    assert [p for p in problems if "401" not in p] == []
    context.close()


def test_vendored_assets_match_their_checksums_and_the_size_budget() -> None:
    table = (STATIC / "ASSETS.md").read_text()
    listed = dict(re.findall(r"\| `([^`]+)` \| \d+ \| `([0-9a-f]{64})` \|", table))
    assert set(listed) == {"uPlot.iife.min.js", "uPlot.min.css", "uPlot.LICENSE"}
    for name, digest in listed.items():
        assert hashlib.sha256((STATIC / name).read_bytes()).hexdigest() == digest, name
    total = sum(p.stat().st_size for p in STATIC.iterdir() if p.suffix != ".md")
    assert total <= 300 * 1024
    for page_file in ("index.html", "app.js", "trend.js", "capture.js", "style.css"):
        text = (STATIC / page_file).read_text()
        assert not re.search(r"https?://", text), page_file  # no other host named
    assert "<script>" not in (STATIC / "index.html").read_text()  # no inline script

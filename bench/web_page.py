"""The live page in a real browser: publish → render latency, streaming, asset size.

Debian's chromium (headless, Playwright, as in tests/integration/test_web_browser.py)
opens the page of ``motion-server run`` (the demo map, anonymous operator) with 8 trend
channels (position and velocity of the four axes), Axis1 jogging.

- **publish → render** (manual clock): the bench steps one cycle over Modbus; the step
  is answered once the cycle ran and its image was published, and that moment
  (``time.time()``) is the publish time of its tick. The page records, for every chart
  render, the newest tick drawn and ``Date.now()`` (``msView.drawn``, after uPlot drew in
  the animation frame). Latency of a tick = first render that drew it − its publish time
  (the same system clock, 1 ms resolution). Steps are spaced 30–60 ms apart at random so
  each sample sees the server's frame batching (about every 20 ms) at a random phase.
  Target: p95 ≤ 100 ms.
- **streaming** (realtime clock, ``--seconds``): ticks advanced (``Clock.Cycle``) against
  rows the page holds, the gaps it counted, renders per second.
- **assets**: the bytes of every file under ``web_static`` (the page loads them all but
  ASSETS.md). Target: ≤ 300 KB.

``--screenshots DIR`` also writes the documentation's screenshots (docs/web/*.png).

Usage: ``python bench/web_page.py [--samples 200] [--seconds 10] [--screenshots docs/web]``.
"""

from __future__ import annotations

import argparse
import os
import random
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.web_browser_support import SKIP_REASON, STATIC, chromium  # noqa: E402

CHANNELS = [f"Axis{n}.{f}" for n in range(1, 5) for f in ("ActualPosition", "ActualVelocity")]
ASSET_BUDGET = 300 * 1024


def load_average() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def percentile(samples: list[float], q: float) -> float:
    s = sorted(samples)
    return s[min(len(s) - 1, int(q * len(s)))]


def set_channels(page: Any, srv: Any, channels: list[str]) -> None:
    page.evaluate("(c) => msView.trendChannels(c)", channels)
    for _ in range(100):
        srv.step(1)
        if page.evaluate(
            "(c) => !!msView.layout && msView.layout.channels.join() === c", ",".join(channels)
        ):
            return
        time.sleep(0.05)
    raise RuntimeError("the trend layout never took effect")


def first_at(marks: list[list[float]], tick: int) -> float | None:
    """The time of the first mark (``[tick, ms]``, in order) whose tick is ≥ ``tick``."""
    return next((at for tk, at in marks if tk >= tick), None)


def latency(page: Any, srv: Any, samples: int) -> tuple[list[float], list[float]]:
    """Publish → render and, of that, frame arrival → render, per stepped tick (ms)."""
    tick = int(srv.read("Clock.Cycle"))
    published: dict[int, float] = {}
    for _ in range(samples):
        srv.step(1)
        tick += 1
        published[tick] = time.time() * 1000.0
        time.sleep(random.uniform(0.030, 0.060))
    page.wait_for_function("(t) => msView.drawn.length && msView.drawn.at(-1)[0] >= t", arg=tick)
    drawn = page.evaluate("msView.drawn")
    arrived = page.evaluate("msView.arrived")
    total, page_part = [], []
    for t, at in published.items():
        shown = first_at(drawn, t)
        came = first_at(arrived, t)
        if shown is not None and came is not None:
            total.append(shown - at)
            page_part.append(shown - came)
    return total, page_part


def streaming(page: Any, srv: Any, seconds: float) -> dict[str, float]:
    page.click("#clear")
    srv.write("Clock.Mode", 0)  # realtime
    c0 = int(srv.read("Clock.Cycle"))
    renders = page.evaluate("msView.renders")
    time.sleep(seconds)
    srv.write("Clock.Mode", 1)  # manual: the last ticks stay put
    c1 = int(srv.read("Clock.Cycle"))
    page.wait_for_function("(t) => msView.rows().length && msView.rows().at(-1)[0] >= t", arg=c1)
    first, last, rows, gap_ticks, renders_after = page.evaluate(
        "[msView.rows()[0][0], msView.rows().at(-1)[0], msView.rows().length, msView.gapTicks,"
        " msView.renders]"
    )
    return {
        "ticks": c1 - c0,
        "rows": rows,
        "span": last - first + 1,
        "renders_per_s": (renders_after - renders) / seconds,
        "gap_ticks": gap_ticks,
    }


def assets() -> tuple[dict[str, int], int]:
    sizes = {p.name: p.stat().st_size for p in sorted(STATIC.iterdir()) if p.suffix != ".md"}
    return sizes, sum(sizes.values())


def small_png(path: Path) -> None:
    """Quantise a screenshot to 64 colours: a third of the bytes, still sharp."""
    try:
        from PIL import Image
    except ImportError:
        return
    with Image.open(path) as img:
        img.convert("RGB").quantize(64).save(path, optimize=True)


def screenshots(browser: Any, srv: Any, url: str, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    ctx = browser.new_context(viewport={"width": 1280, "height": 800})
    page = ctx.new_page()
    page.goto(url)
    page.wait_for_function("() => window.msView && msView.statusCount > 0")
    srv.trigger("MSO_1")
    set_channels(page, srv, ["Axis1.ActualPosition", "Axis1.ActualVelocity", "MAJ_1.IP"])
    page.click("#clear")
    srv.step(20)
    srv.trigger("MAJ_1")
    srv.step(230)
    page.fill("#window-rows", "400")
    page.wait_for_timeout(300)
    ticks = page.evaluate("msView.rows().map((r) => r[0])")
    page.evaluate(
        "([a, b]) => { msView.setCursor('A', a); msView.setCursor('B', b); }",
        [ticks[40], ticks[140]],
    )
    page.wait_for_timeout(300)
    page.screenshot(path=out / "overview.png")
    page.locator("#trend").screenshot(path=out / "trend.png")
    page.fill("#instr-filter", "MA")
    page.locator('tr[data-instruction="MAJ_1"] button.arm').click()
    page.wait_for_timeout(200)
    page.locator("#instructions").screenshot(path=out / "instructions.png")
    # a trigger on the DN edge of an MAS that stops the jog: pre and post rows around it
    page.fill("#instr-filter", "")
    page.click("#zoom-reset")
    page.evaluate("() => { msView.setCursor('A', null); msView.setCursor('B', null); }")
    set_channels(page, srv, ["Axis1.ActualPosition", "Axis1.ActualVelocity", "MAS_1.DN"])
    page.select_option("#trig-channel", "MAS_1.DN")
    page.fill("#trig-pre", "60")
    page.fill("#trig-post", "120")
    page.click("#trig-arm")
    srv.step(80)
    srv.trigger("MAS_1")
    srv.step(150)
    page.wait_for_function("() => msView.trigger.state === 'triggered'")
    page.wait_for_timeout(300)
    page.locator("#trend").screenshot(path=out / "trigger.png")
    ctx.close()
    for name in ("overview.png", "trend.png", "instructions.png", "trigger.png"):
        small_png(out / name)
        print(f"  {out / name}: {(out / name).stat().st_size} bytes")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--screenshots", type=Path, default=None)
    args = ap.parse_args()
    sizes, total = assets()
    print(f"load average before: {load_average()}")
    print(f"static assets: {total} bytes ({total / 1024:.1f} KiB) of {ASSET_BUDGET // 1024} KiB")
    for name, size in sizes.items():
        print(f"  {name}: {size}")
    if SKIP_REASON is not None:
        print(f"browser part skipped: {SKIP_REASON}")
        return 0
    from motion_server.testing import MotionServer

    with tempfile.TemporaryDirectory() as work:
        srv = MotionServer.start(work, opcua=False, web=True)
        try:
            with chromium() as browser:
                if args.screenshots is not None:
                    screenshots(browser, srv, srv.web_url, args.screenshots)
                    srv.write("Clock.Mode", 1)
                page = browser.new_page(viewport={"width": 1280, "height": 900})
                page.goto(srv.web_url)
                page.wait_for_function("() => window.msView && msView.statusCount > 0")
                srv.trigger("MSO_1")
                srv.trigger("MAJ_1")
                set_channels(page, srv, CHANNELS)
                lat, in_page = latency(page, srv, args.samples)
                for label, xs in (
                    ("publish → render", lat),
                    ("  of which frame → render", in_page),
                ):
                    print(
                        f"{label}, {len(xs)} stepped ticks, 8 channels: "
                        f"p50 {percentile(xs, 0.5):.0f} ms, p95 {percentile(xs, 0.95):.0f} ms, "
                        f"p99 {percentile(xs, 0.99):.0f} ms, max {max(xs):.0f} ms"
                    )
                print("target: publish → render p95 ≤ 100 ms")
                s = streaming(page, srv, args.seconds)
                print(
                    f"realtime {args.seconds:.0f} s, 8 channels: {s['ticks']} ticks advanced; "
                    f"the page holds {s['rows']} rows spanning {s['span']} ticks, "
                    f"{s['gap_ticks']} ticks missing; {s['renders_per_s']:.0f} renders/s"
                )
        finally:
            srv.stop()
    print(f"load average after: {load_average()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

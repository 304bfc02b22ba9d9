"""The flight report page in a real browser: a mission flown on the real
vehicle over pymavlink (mission, geofence, rally point, a GPS failure
injected and cleared), its flight record turned into a page by
`rotorpilot report`, opened in headless Chromium (Debian's, via Playwright:
no browser download), offline. Checked: no console error, no page error, no
network request, every section present with data; a screenshot is saved
(REPORT_SCREENSHOT, default target/report-screenshot.png). The same checks
are shown to fail on a page with a section removed, a script error injected
or a request to the network.

Run by tools/test-all.sh in the `report` venv:
  ROTORPILOT_BIN=target/release/rotorpilot .venv/report/bin/python -m pytest -q tests/report
"""

import math
import os
import re
import subprocess
import sys
import tempfile
import time

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, "python"))

from rotorpilot import Vehicle  # noqa: E402

CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
# a closed network: no GPU, no QUIC, nothing in the background
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
PLOTS = ["altitude", "speed", "attitude", "tracking", "rotors", "force", "torque", "mass", "battery"]
SECTIONS = ["verdict", "path", "timeline", "plots", "events"]
HOME = (47.397742, 8.545594)
D = 1e-4  # degrees: ~11 m north, ~7.5 m east


def _upload(m, kind, items):
    """The mission protocol by hand: MISSION_COUNT, an item per request, the ACK."""
    m.mav.mission_count_send(1, 1, len(items), kind)
    deadline = time.time() + 10
    while time.time() < deadline:
        r = m.recv_match(type=["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], blocking=True, timeout=1)
        if r is None:
            continue
        if r.get_type() == "MISSION_ACK":
            assert r.type == 0, f"plan type {kind} refused: {r.type}"
            return
        cmd, p1, lat, lon, alt = items[r.seq]
        m.mav.mission_item_int_send(1, 1, r.seq, 6, cmd, 0, 1, p1, 0, 0, math.nan,
                                    int(lat * 1e7), int(lon * 1e7), alt, kind)
    raise AssertionError(f"upload of plan type {kind} did not finish")


def _command(m, cmd, *p):
    p = list(p) + [0] * (7 - len(p))
    m.mav.command_long_send(1, 1, cmd, 0, *p)
    ack = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)
    assert ack is not None and ack.result == 0, f"command {cmd}: {ack}"


MISSION = [(22, 0, HOME[0], HOME[1], 5), (16, 0, HOME[0] + 2 * D, HOME[1], 6),
           (16, 0, HOME[0] + 2 * D, HOME[1] + 3 * D, 8), (16, 0, HOME[0], HOME[1] + 3 * D, 6),
           (21, 0, HOME[0], HOME[1], 0)]
FENCE = [(5001, 4, HOME[0] - 3 * D, HOME[1] - 3 * D, 0), (5001, 4, HOME[0] + 5 * D, HOME[1] - 3 * D, 0),
         (5001, 4, HOME[0] + 5 * D, HOME[1] + 6 * D, 0), (5001, 4, HOME[0] - 3 * D, HOME[1] + 6 * D, 0),
         (5004, 6, HOME[0] + 3.5 * D, HOME[1] + 1.5 * D, 0)]
RALLY = [(5100, 0, HOME[0] - 1.5 * D, HOME[1] + 1.5 * D, 10)]


@pytest.fixture(scope="module")
def record():
    """Fly the mission at 20x with a GPS failure injected mid-way; the flight record."""
    from pymavlink import mavutil

    root = tempfile.mkdtemp(prefix="rotorpilot-report-")
    speed = 20.0
    v = Vehicle(speed=speed, root=root, params={"SYS_FAILURE_EN": 1})
    v.start()
    try:
        m = mavutil.mavlink_connection(v.pymavlink_url, source_system=255)
        assert m.wait_heartbeat(timeout=10) is not None
        _upload(m, 0, MISSION)
        _upload(m, 1, FENCE)
        _upload(m, 2, RALLY)
        _command(m, 400, 1)        # arm
        _command(m, 300, 0, 0)     # MISSION_START
        start = time.time()
        sim = lambda: (time.time() - start) * speed  # noqa: E731
        while sim() < 30:
            m.recv_match(blocking=True, timeout=0.2)
        _command(m, 420, 4, 1, 0)  # GPS off
        while sim() < 36:
            m.recv_match(blocking=True, timeout=0.2)
        _command(m, 420, 4, 0, 0)  # GPS ok
        while sim() < 45:
            m.recv_match(blocking=True, timeout=0.2)
        m.close()
    finally:
        assert v.stop() == 0
    assert os.path.exists(v.record)
    return v.record


@pytest.fixture(scope="module")
def page_path(record, tmp_path_factory):
    out = str(tmp_path_factory.mktemp("page") / "flight.html")
    r = subprocess.run([os.environ["ROTORPILOT_BIN"], "report", record, "-o", out,
                        "--test", "tests/report/test_report_page.py::test_a_mission"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "wrote" in r.stdout
    return out


@pytest.fixture(scope="module")
def browser():
    from playwright.sync_api import sync_playwright

    assert os.path.exists(CHROMIUM), f"no {CHROMIUM}: apt-get install chromium"
    profile = tempfile.mkdtemp(prefix="rotorpilot-chromium-")
    with sync_playwright() as p:
        # a persistent context is the one that takes a fresh --user-data-dir
        ctx = p.chromium.launch_persistent_context(profile, executable_path=CHROMIUM, headless=True,
                                                   args=ARGS, viewport={"width": 1400, "height": 900})
        yield ctx
        ctx.close()


def open_page(ctx, path, screenshot=None):
    """Open `path` offline; every problem as a list of strings (empty: the
    page is whole), and the page's own account (window.__report)."""
    problems = []
    page = ctx.new_page()
    page.on("console", lambda m: m.type == "error" and problems.append(f"console error: {m.text}"))
    page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
    url = "file://" + os.path.abspath(path)

    def request(req):
        if req.url != url and not req.url.startswith("data:"):
            problems.append(f"network request: {req.url}")

    page.on("request", request)
    # nothing leaves the browser whatever the page asks
    page.route(re.compile(r"^(https?|wss?|ftp)://"), lambda route: route.abort())
    start = time.monotonic()
    page.goto(url)
    try:
        page.wait_for_selector("body[data-ready='1']", timeout=10000)
    except Exception as e:  # noqa: BLE001 - reported as a problem of the page
        problems.append(f"never ready: {type(e).__name__}")
    open_s = time.monotonic() - start
    account = page.evaluate("() => window.__report || null")
    for s in SECTIONS:
        if page.locator(f"section#{s}, header#{s}").count() != 1:
            problems.append(f"section {s} missing")
    if account is None:
        problems.append("no window.__report: the plots were not drawn")
    else:
        drawn = {p["id"]: p for p in account["plots"]}
        for name in PLOTS:
            p = drawn.get(name)
            if p is None or p["series"] == 0 or p["points"] == 0:
                problems.append(f"plot {name} has no data: {p}")
            elif page.locator(f"#plot-{name} canvas").count() == 0:
                problems.append(f"plot {name} has no canvas")
    points = page.locator("#track").get_attribute("data-points") if page.locator("#track").count() else "0"
    if int(points or 0) < 100:
        problems.append(f"the path has {points} points")
    if page.locator("#path-svg g.item").count() != 5:
        problems.append(f"{page.locator('#path-svg g.item').count()} mission items on the path, not 5")
    if page.locator("#path-svg .fence-in").count() != 1 or page.locator("#path-svg .fence-out").count() != 1:
        problems.append("the fence (a polygon and a circle) is not drawn")
    if page.locator("#path-svg g.rally").count() != 1:
        problems.append("the rally point is not drawn")
    if page.locator("#tl-mode .tl-span").count() < 2 or page.locator("#tl-arming .tl-span").count() < 2:
        problems.append("the modes/arming timeline is empty")
    if page.locator("#events tr.failure").count() != 2:
        problems.append("the two failure injections are not in the events")
    if page.locator("#events tr.reached").count() < 3:
        problems.append("fewer than 3 items reached in the events")
    if screenshot:
        os.makedirs(os.path.dirname(os.path.abspath(screenshot)), exist_ok=True)
        page.screenshot(path=screenshot, full_page=True)
    page.close()
    return problems, account, open_s


def test_the_page_opens_offline_with_every_section(page_path, browser):
    shot = os.environ.get("REPORT_SCREENSHOT", os.path.join(ROOT, "target", "report-screenshot.png"))
    problems, account, open_s = open_page(browser, page_path, screenshot=shot)
    assert problems == [], problems
    assert account["samples"] > 100
    assert os.path.getsize(shot) > 50_000
    html = open(page_path, encoding="utf-8").read()
    assert "test_a_mission" in html and "CMD_INJECT_FAILURE, GPS off" in html
    # nothing the page could fetch: no src/href to another place
    assert not re.search(r"(src|href)=\"(https?:)?//", html)
    print(f"page {os.path.getsize(page_path) / 1e6:.2f} MB opened in {open_s:.2f} s; screenshot {shot}")


@pytest.mark.parametrize("breakage", ["section", "script", "network"])
def test_the_checks_fail_on_a_broken_page(page_path, browser, tmp_path, breakage):
    html = open(page_path, encoding="utf-8").read()
    if breakage == "section":
        broken = re.sub(r"<section id=\"path\">.*?</section>", "", html, count=1, flags=re.S)
    elif breakage == "script":
        broken = html.replace("</body>", "<script>throw new Error('injected');</script></body>")
    else:
        broken = html.replace("</body>", "<img src=\"http://192.0.2.1/x.png\"></body>")
    assert broken != html
    path = tmp_path / "broken.html"
    path.write_text(broken, encoding="utf-8")
    problems, _, _ = open_page(browser, str(path))
    assert problems, f"a page broken by {breakage} passed the checks"

"""The Snake and MAHRU views in a real browser (Playwright driving
Debian's Chromium), each against its own `firelink web --robot ...` on the
simulated bus: the printed URL opens the robot's view (not the dVRK's),
its values update, a command clicked on the page reaches the robot and
shows in the state the server reports (the Snake's torque/speed switch and
wiper on one channel, an EEPROM word, the lifecycle, a jog and a board
loss; MAHRU's enable and gait start with its phase and time budget), a
malformed command is refused with its reason; screenshots are saved.

Needs FIRELINK_WEB_BIN and, optionally, CHROMIUM and SCREENSHOT_DIR (as
test_console.py). Nothing is timed: every wait polls for a state, bounded
only so that a broken build fails instead of hanging.
"""

from __future__ import annotations

import json
import os
import subprocess
import urllib.error
import urllib.request

import pytest
from playwright.sync_api import Page, expect

from test_console import BIN, CHROMIUM, SHOTS, WAIT_MS, base_and_token, server_state  # noqa: F401
from test_console import browser  # noqa: F401  (the shared fixture)


def start_console(robot: str):
    proc = subprocess.Popen(
        [BIN, "--robot", robot, "--port", "sim", "--listen", "127.0.0.1:0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    line = proc.stdout.readline()
    assert line.startswith("firelink web: http://127.0.0.1:"), line + proc.stderr.read()
    return proc, line.split("firelink web: ", 1)[1].strip()


def stop_console(proc):
    proc.terminate()
    assert proc.wait(timeout=60) == 0, proc.stderr.read()


@pytest.fixture(scope="module")
def snake():
    proc, url = start_console("snake")
    try:
        yield url
    finally:
        stop_console(proc)


@pytest.fixture(scope="module")
def mahru():
    proc, url = start_console("mahru")
    try:
        yield url
    finally:
        stop_console(proc)


def open_page(browser, url: str) -> Page:  # noqa: F811
    pg = browser.new_page(viewport={"width": 1400, "height": 1200})
    pg.set_default_timeout(WAIT_MS)
    pg.goto(url)
    return pg


def open_view(browser, url: str, robot: str, rows: dict[str, int]) -> Page:  # noqa: F811
    """The page at `url`, showing `robot`'s view (not the dVRK's) live,
    with `rows[table]` rows in each table."""
    page = open_page(browser, url)
    expect(page.locator(f"#{robot}-view")).to_be_visible()
    expect(page.locator("#dvrk-view")).to_be_hidden()
    for table, count in rows.items():
        expect(page.locator(f"{table} tbody tr")).to_have_count(count)
    expect(page.locator("#link")).to_have_text("live")
    return page


def post_raw(url: str, body: str) -> tuple[int, dict]:
    base, token = base_and_token(url)
    req = urllib.request.Request(
        base + "/api/command", data=body.encode(), method="POST",
        headers={"X-Firelink-Token": token, "Origin": base, "Content-Type": "application/json"},
    )
    try:
        with urllib.request.urlopen(req, timeout=60) as r:
            return r.status, json.load(r)
    except urllib.error.HTTPError as e:
        return e.code, json.load(e)


def click_and_answer(page: Page, selector: str) -> int:
    with page.expect_response("**/api/command") as answer:
        page.click(selector)
    return answer.value.status


def test_snake_view_shows_36_axes_and_its_values_update(browser, snake):  # noqa: F811
    page = open_view(browser, snake, "snake", {"#snake-axes": 36, "#snake-nodes": 6})
    expect(page.locator("#summary")).to_contain_text("Snake: 6 nodes, 36 axes")
    # The robot's clock moves on the page, and the selected axis's chart
    # fills.
    first = page.evaluate("() => live.state.t")
    page.wait_for_function(f"() => live.state.t > {first}")
    page.wait_for_function("() => robotView.charts.axis.data[0].length > 5")
    last = page.evaluate("() => robotView.charts.axis.data[0].at(-1)")
    page.wait_for_function(f"() => robotView.charts.axis.data[0].at(-1) > {last}")
    page.close()


def test_snake_channel_functions_reach_the_node(browser, snake):  # noqa: F811
    page = open_page(browser, snake)
    expect(page.locator("#snake-axes tbody tr")).to_have_count(36)
    axis = 9
    page.select_option("#snake-axis", str(axis))
    row = page.locator(f"#snake-axes tbody tr[data-axis='{axis}']")
    expect(row.locator("td.mode")).to_have_text("torque")
    assert click_and_answer(page, "#snake-speed") == 200
    expect(page.locator("#last-command")).to_contain_text(f"axis {axis} speed mode: ok")
    expect(row.locator("td.mode")).to_have_text("speed")
    st = server_state(snake)
    assert st["axes"][axis]["speed_mode"] is True
    assert st["axes"][axis - 1]["speed_mode"] is False
    page.fill("#snake-wiper", "649")
    assert click_and_answer(page, "#snake-set-wiper") == 200
    expect(page.locator("#last-command")).to_contain_text("wiper 649 (read back)")
    assert server_state(snake)["axes"][axis]["wiper"] == 649
    # EEPROM: write-protected at first (the refusal says so), then written.
    page.fill("#snake-word", "2")
    page.fill("#snake-value", "4660")
    assert click_and_answer(page, "#snake-eeprom-write") == 500
    expect(page.locator("#last-command")).to_contain_text("write protection is on")
    assert click_and_answer(page, "#snake-protect-off") == 200
    assert click_and_answer(page, "#snake-eeprom-write") == 200
    assert click_and_answer(page, "#snake-eeprom-read") == 200
    expect(page.locator("#last-command")).to_contain_text("word 2: 4660 (0x1234)")
    page.screenshot(path=str(SHOTS / "console-snake-channel.png"), full_page=True)
    # Back to torque mode and the nominal wiper before powering on.
    assert click_and_answer(page, "#snake-torque") == 200
    page.fill("#snake-wiper", "375")
    assert click_and_answer(page, "#snake-set-wiper") == 200
    page.close()


def test_snake_lifecycle_and_a_jog(browser, snake):  # noqa: F811
    page = open_page(browser, snake)
    expect(page.locator("#snake-axes tbody tr")).to_have_count(36)
    # Unconfigured: a jog is refused by the robot's state.
    page.select_option("#snake-axis", "0")
    assert click_and_answer(page, "#snake-jog-plus") == 409
    expect(page.locator("#last-command")).to_have_attribute("data-result", "refused")
    for action in ["configure", "power_on", "home", "enable"]:
        assert click_and_answer(page, f"#snake-view button[data-robot-action={action}]") == 200, action
    expect(page.locator("#state")).to_have_text("active")
    before = server_state(snake)["axes"][0]["setpoint"]
    page.fill("#snake-jog", "0.05")
    assert click_and_answer(page, "#snake-jog-plus") == 200
    page.wait_for_function(f"() => Math.abs(live.state.axes[0].setpoint - ({before} + 0.05)) < 1e-9")
    st = server_state(snake)
    assert st["state"] == "active" and all(a["amp"] for a in st["axes"])
    expect(page.locator("#snake-safety")).to_contain_text("36 of 36 amplifiers on")
    page.screenshot(path=str(SHOTS / "console-snake-active.png"), full_page=True)
    assert click_and_answer(page, "#snake-view button[data-robot-action=disable]") == 200
    expect(page.locator("#state")).to_have_text("configured")
    page.close()


def test_snake_refuses_malformed_commands_with_a_reason(snake):
    status, body = post_raw(snake, '{"action":"mode","axis":99,"speed":true}')
    assert status == 400 and "axis 99 does not exist" in body["detail"], body
    status, body = post_raw(snake, '{"action":"warp"}')
    assert status == 400 and "unknown variant" in body["detail"], body


def test_snake_board_loss_shows_the_fault(browser, snake):  # noqa: F811
    page = open_view(browser, snake, "snake", {"#snake-axes": 36, "#snake-nodes": 6})
    expect(page.locator("#state")).to_have_text("configured")
    for action in ["power_on", "enable"]:
        assert click_and_answer(page, f"#snake-view button[data-robot-action={action}]") == 200, action
    expect(page.locator("#state")).to_have_text("active")
    assert click_and_answer(page, "#snake-faults button[data-fault=board-loss]") == 200
    expect(page.locator("#state")).to_have_text("fault")
    expect(page.locator("#snake-view .robot-fault")).to_contain_text("board 4")
    expect(page.locator("#snake-safety")).to_contain_text("not answering: nodes 4")
    expect(page.locator("#snake-nodes tbody tr[data-node='4'] td").nth(1)).to_have_text("no")
    assert server_state(snake)["state"] == "fault"
    page.screenshot(path=str(SHOTS / "console-snake-fault.png"), full_page=True)
    page.close()


def test_mahru_view_enables_and_walks(browser, mahru):  # noqa: F811
    page = open_view(browser, mahru, "mahru", {"#mahru-modules": 14, "#mahru-ft": 4})
    expect(page.locator("#summary")).to_contain_text("MAHRU: 14 modules")
    # Disabled: the gait is refused, with the reason.
    assert click_and_answer(page, "#mahru-view button[data-robot-action=gait_start]") == 409
    expect(page.locator("#last-command")).to_contain_text("enable first")
    assert click_and_answer(page, "#mahru-view button[data-robot-action=enable]") == 200
    expect(page.locator("#state")).to_have_text("enabled")
    # The budget fills in, and the feet carry the body.
    page.wait_for_function("() => live.state.budget.periods > 10 && live.state.budget.busy_us > 0")
    expect(page.locator("#mahru-budget-summary")).to_contain_text("of 2000 us available")
    page.wait_for_function("() => robotView.charts.budget.data[0].length > 5 && robotView.charts.module.data[0].length > 5")
    assert page.evaluate("() => robotView.charts.budget.data[2].at(-1)") == 2000
    assert click_and_answer(page, "#mahru-view button[data-robot-action=gait_start]") == 200
    expect(page.locator("#mahru-walking")).to_have_text("walking")
    page.wait_for_function("() => live.state.gait.time_s > 0.5")
    st = server_state(mahru)
    assert st["gait"]["walking"] is True and st["state"] == "enabled", st
    assert 0.0 <= st["gait"]["phase"] < 1.0
    assert st["missed"] == 0
    assert any(any(x != 0.0 for x in m["wrench"]) for m in st["modules"]), st
    expect(page.locator("#mahru-phase-text")).to_contain_text("phase")
    page.screenshot(path=str(SHOTS / "console-mahru-walking.png"), full_page=True)
    assert click_and_answer(page, "#mahru-view button[data-robot-action=gait_stop]") == 200
    expect(page.locator("#mahru-walking")).to_have_text("holding")
    assert click_and_answer(page, "#mahru-view button[data-robot-action=disable]") == 200
    expect(page.locator("#state")).to_have_text("stopped")
    page.close()

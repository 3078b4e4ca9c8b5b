"""The bench page in a real (headless) Chromium: the oscilloscope fills, the speed knob is
moved in the page, the server restamps R33/R44, and the plotted data go on from the state
reached: the hunting that grew at 57 m/s decays at 54 m/s."""

import os
import shutil
import time

import numpy as np
import pytest

from tests.bench.cdp import Chromium, chromium_binary
from tests.bench.live import PATIENCE, BenchProcess, request, wait_for_model_time

CHROMIUM = chromium_binary()

pytestmark = pytest.mark.skipif(
    CHROMIUM is None,
    reason="chromium is not installed (apt-get install -y chromium chromium-driver; CI "
    "installs it)",
)

#: The page's plotted data and widgets, read from Bokeh's document in the browser.
PAGE_DATA = """(() => {
  if (typeof Bokeh === 'undefined') return null;  // the page is still loading
  const doc = Bokeh.documents[0];
  if (doc === undefined) return null;
  const source = doc.get_model_by_name('trace_y');
  if (source === null || source.data.t.length === 0) return null;
  return {t: Array.from(source.data.t), y: Array.from(source.data.circuit),
          ode: Array.from(source.data.ode),
          parts: doc.get_model_by_name('parts_speed').text,
          speed: doc.get_model_by_name('knob_speed').value};
})()"""

MOVE_SPEED = """(() => {
  const knob = Bokeh.documents[0].get_model_by_name('knob_speed');
  knob.value = 54;
  knob.value_throttled = 54;  // what a mouse release sends: the server's callback runs
  return knob.value;
})()"""


def page_data(browser: Chromium, after: float = -1.0) -> dict:
    """The plotted data once the page shows samples past model time ``after``."""
    deadline = time.monotonic() + PATIENCE
    while time.monotonic() < deadline:
        data = browser.evaluate(PAGE_DATA)
        if data is not None and data["t"][-1] > after:
            return data
        time.sleep(0.3)
    raise AssertionError(f"the page showed no samples past t = {after} s")


def peak(data: dict, start: float, end: float) -> float:
    t, y = np.array(data["t"]), np.abs(data["y"])
    return float(y[(t > start) & (t <= end)].max())


@pytest.fixture(scope="module")
def browser_on_bench():
    server = BenchProcess(  # held until the page is up
        "--speed", "57", "--amplitude", "0", "--no-flange", "--y0", "0.005", "--rate", "1",
        "--paused",
    )  # fmt: skip
    browser = Chromium(CHROMIUM)
    try:
        browser.call("Page.enable")
        browser.call("Page.navigate", url=server.url)
        yield server.url, browser
    finally:
        browser.close()
        server.stop()


def test_moving_the_speed_knob_in_the_page_changes_the_plotted_data(browser_on_bench, tmp_path):
    url, browser = browser_on_bench
    page_data(browser)  # the page is up and plotting
    _, answer = request(url + "api/set_state", {"y": 0.005, "psi": 0, "y_dot": 0, "psi_dot": 0})
    t_push = answer["t_applied"]  # a fresh 5 mm push from rest
    assert request(url + "api/run", {"running": True})[1]["running"] is True
    wait_for_model_time(url, t_push + 4.0)
    before = page_data(browser)
    assert before["speed"] == 57
    _, state = request(url + "api/state")
    assert f"R33 = {state['resistors']['R33'] / 1e3:.4g} kΩ" in before["parts"]

    assert browser.evaluate(MOVE_SPEED) == 54  # while it runs
    deadline = time.monotonic() + PATIENCE
    while request(url + "api/state")[1]["knobs"]["speed"] != 54:
        assert time.monotonic() < deadline, "the page's knob did not reach the server"
        time.sleep(0.1)
    _, history = request(url + "api/history")
    change = history["events"][-1]
    assert change["kind"] == "knobs" and change["values"] == {"speed": 54}
    t_applied = change["t"]
    wait_for_model_time(url, t_applied + 5.0)
    t_end = request(url + "api/run", {"running": False})[1]["t"]  # hold it for the picture

    after = page_data(browser, after=t_end - 1e-6)
    _, state = request(url + "api/state")
    assert f"R33 = {state['resistors']['R33'] / 1e3:.4g} kΩ" in after["parts"]
    assert after["parts"] != before["parts"] and after["speed"] == 54
    # the plotted data go on through the change (one clock, no restart) and decay
    t = np.array(after["t"])
    assert t[0] < t_applied < t[-1] and np.all(np.diff(t) > 0)
    assert peak(after, t_end - 1.0, t_end) < 0.7 * peak(after, t_applied - 1.0, t_applied)
    # ... after growing at 57 m/s since the push
    _, trace = request(url + f"api/trace?since={t_push}")
    scope = {"t": trace["t"], "y": trace["states"]["y"]}
    assert peak(scope, t_applied - 1, t_applied) > 1.5 * peak(scope, t_push, t_push + 1)
    # what the page plots is the session's trace
    shown = {round(a, 9): b for a, b in zip(after["t"], after["y"], strict=True)}
    common = [(shown[round(a, 9)], b) for a, b in zip(trace["t"], trace["states"]["y"],
              strict=True) if round(a, 9) in shown]  # fmt: skip
    assert len(common) > 1000
    np.testing.assert_allclose(*zip(*common, strict=True), rtol=1e-12, atol=0)

    picture = tmp_path / "bench.png"
    browser.screenshot(picture)
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and picture.stat().st_size > 20_000
    target = os.environ.get("CIRCUITSIM_BENCH_SCREENSHOT")
    if target:  # docs/figures/bench.png is made so
        shutil.copyfile(picture, target)

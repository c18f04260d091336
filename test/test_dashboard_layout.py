"""What the clinician sees (issue 48 items 3-5) in headless chromium, fed by hand-made messages.

The biofeedback node gets a calibration progress status, strides before and after a calibration and
then stops; the page must say what is true at each moment ("not calibrated yet: no feedback", the
progress, cues in clinical words, "session ended" with the last values), show each value once
(the Gait panel and the Targets table read the same stride), and fit a 1280x800 laptop and a
1024x768 tablet without horizontal scrolling or a clipped axis label. The screenshots go to a
temporary folder whose paths are printed (``pytest -s``).
"""

from __future__ import annotations

import contextlib
import math
import time

import pytest
from conftest import find_chromium, spinning_in_background

pytestmark = [pytest.mark.ros, pytest.mark.timeout(90),
              pytest.mark.skipif(find_chromium() is None, reason="chromium not installed: run "
                                 "`bash scripts/setup_browser.sh` (apt-get install chromium)")]

SIZES = ((1280, 800), (1024, 768))
STRIDE_S = 1.5  # s: cadence 2 / 1.5 steps/s = 80 steps/min, below the 96-126 of config/targets.yaml


def _cycle(side: str, index: int, start: float, flag: str = ""):
    from gait_biofeedback.wire.stamps import ns_to_stamp
    from gait_biofeedback_msgs.msg import GaitCycle

    end = start + STRIDE_S
    msg = GaitCycle(side=0 if side == "left" else 1, stride_index=index, stride_time=STRIDE_S,
                    stance_time=0.93, swing_time=0.57, stance_fraction=0.62, swing_fraction=0.38,
                    step_time=STRIDE_S / 2, cadence=2.0 / STRIDE_S, step_time_symmetry_index=0.0,
                    plausible=True, stride_length=1.8, gait_speed=1.8 / STRIDE_S, max_foot_height=0.12,
                    foot_angle_ic=math.radians(20), turning_angle=0.0, spatial_flag=flag)
    msg.header.stamp = ns_to_stamp(round(end * 1e9))
    msg.start = ns_to_stamp(round(start * 1e9))
    msg.terminal_contact = ns_to_stamp(round((start + 0.93) * 1e9))
    return msg


def _text(browser, element: str) -> str:
    return browser.evaluate(f"document.getElementById('{element}').textContent")


def _until(browser, element: str, ready, timeout: float = 10.0) -> str:
    deadline = time.monotonic() + timeout
    while True:
        text = _text(browser, element)
        if ready(text) or time.monotonic() > deadline:
            return text
        time.sleep(0.1)


def _fits(browser, tmp_path, moment: str) -> list[str]:
    """At each size: no horizontal scrolling, no clipped axis label; a screenshot each (paths)."""
    paths = []
    for width, height in SIZES:
        browser.call("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1,
                     mobile=False)
        time.sleep(0.5)  # a few animation frames: the canvases take their new size
        scroll, inner, clipped = browser.evaluate(
            "[document.documentElement.scrollWidth, innerWidth, window.dashboardState.clippedLabelsNow]")
        assert inner == width and scroll <= inner, f"{moment}, {width}x{height}: {scroll} px wide"
        assert clipped == 0, f"{moment}, {width}x{height}: {clipped} axis labels cut at a canvas edge"
        path = tmp_path / f"dashboard_{moment}_{width}x{height}.png"
        browser.screenshot(path)
        paths.append(str(path))
    return paths


def test_states_values_and_layout_in_headless_chromium(ros_context, tmp_path):
    from rclpy.node import Node
    from test_dashboard_browser import Browser

    from gait_biofeedback.core.calibration.progress import Progress
    from gait_biofeedback.nodes.biofeedback import BiofeedbackNode
    from gait_biofeedback.nodes.common import publisher
    from gait_biofeedback.wire import diagnostics, topics
    from gait_biofeedback.wire.calibration import mounting_msg

    bio = BiofeedbackNode(ros_context, port=0, stride_wait_s=0.0)
    source = Node("hand_made_inputs", context=ros_context)
    cycles, diag, calibration = (publisher(source, t) for t in (topics.GAIT_CYCLES, topics.DIAGNOSTICS,
                                                                 topics.CALIBRATION))
    shots = []
    with spinning_in_background(ros_context, bio, source) as executor, \
            contextlib.closing(Browser(bio.server.url, *SIZES[0])) as browser:
        browser.wait_for(lambda s: s.get("connected") and s.get("hello"), timeout=15)
        # before any calibration: the progress, the strides and temporal values, and no feedback
        progress = Progress(2.04, 3.0, False, {"left": 0, "right": 0})
        diag.publish(diagnostics.array(source.get_clock().now().to_msg(), [diagnostics.status(
            "calibration: progress", diagnostics.OK, progress.text(), values=progress.values())]))
        for k, (side, index) in enumerate((("left", 1), ("right", 1), ("left", 2), ("right", 2))):
            cycles.publish(_cycle(side, index, 10.0 + STRIDE_S / 2 * k))  # each foot's strides continuous
        assert _until(browser, "stat-strides", lambda t: t == "2 / 2") == "2 / 2"
        standing = _until(browser, "progress-standing", lambda t: "2.0 of 3 s" in t)
        assert standing == "Standing still: 2.0 of 3 s"
        assert _text(browser, "stat-cadence") == "80 steps/min"
        assert _text(browser, "stat-stance") == "62.0 % / 62.0 %"
        assert _text(browser, "audio-state") == "not calibrated yet: no feedback"
        assert _text(browser, "calibration-in-force").startswith("Not calibrated yet: no feedback")
        shots += _fits(browser, tmp_path, "before_calibration")

        # calibrated: the cue in clinical words, the tone on hover only
        calibration.publish(mounting_msg({"left_foot": [1.0, 0, 0, 0], "right_foot": [1.0, 0, 0, 0]}, 0,
                                         "walking", "explained_variance"))
        browser.wait_for(lambda s: (s.get("calibrationInForce") or {}).get("valid"), timeout=10)
        cycles.publish(_cycle("left", 3, 13.0))
        assert _until(browser, "stat-strides", lambda t: t == "3 / 2") == "3 / 2"
        audio = _until(browser, "audio-state", lambda t: t.startswith("Take quicker steps"))
        assert audio == ("Take quicker steps — target 96 steps/min to 126 steps/min, "
                         "measured 80 steps/min"), audio
        hover = browser.evaluate("document.getElementById('audio-state').title")
        assert hover.startswith("Tone: ") and " Hz, " in hover and "beeps/s" in hover and "Hz" not in audio
        # one source: the Gait panel and the Targets table show the latest stride's speed, then both "–"
        row = ("[...document.querySelectorAll('#cues tbody tr')]"
               ".map(r => [...r.cells].map(c => c.textContent)).find(c => c[0] === 'Walking speed')")
        assert _until(browser, "stat-speed", lambda t: t == "1.20 m/s") == "1.20 m/s"
        assert browser.evaluate(row)[1] == "1.20 m/s"
        cycles.publish(_cycle("right", 3, 13.75, flag="foot trajectory doubtful"))
        assert _until(browser, "stat-strides", lambda t: t == "3 / 3") == "3 / 3"
        assert _until(browser, "stat-speed", lambda t: t == "–") == "–"
        speed_row = browser.evaluate(row)
        assert speed_row[1] == "–" and "doubtful" in speed_row[4], speed_row
        shots += _fits(browser, tmp_path, "calibrated")

        # the graph stops: the page says so and keeps the last values
        executor.remove_node(bio)
        bio.destroy_node()
        state = browser.wait_for(lambda s: s.get("ended"), timeout=10)
        assert "Session ended" in _text(browser, "session-state") and not state["connected"]
        assert _text(browser, "stat-strides") == "3 / 3" and _text(browser, "stat-cadence") == "80 steps/min"
        audio = _until(browser, "audio-state", lambda t: t.startswith("session ended"))  # next refresh
        assert audio == "session ended: no sound"
        shots += _fits(browser, tmp_path, "ended")
        print("\nscreenshots:\n" + "\n".join(shots))

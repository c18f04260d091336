"""One instruction at a time on the page (issue 49 items 4-6), in headless chromium fed hand-made strides.

Strides at 80 steps/min (below the 96-126 of config/targets.yaml) after a calibration: the node's focus
is the knowledge base's "Take quicker steps"; the page shows it large and speaks it through
``speechSynthesis.speak`` (stubbed in the page to record the call: headless chromium has no voice), the
dose goes on ``biofeedback/given``; muted, the words are shown but not spoken; without a voice the page
sounds its fallback tones instead. The screenshot's path is printed (``pytest -s``).
"""

from __future__ import annotations

import contextlib
import time

import pytest
from conftest import find_chromium, spinning_in_background
from test_dashboard_layout import _cycle, _fits, _text, _until

pytestmark = [pytest.mark.ros, pytest.mark.timeout(90),
              pytest.mark.skipif(find_chromium() is None, reason="chromium not installed: run "
                                 "`bash scripts/setup_browser.sh` (apt-get install chromium)")]

STUB_SPEECH = """
window.spokenWords = [];
window.voices = [{name: "stub", lang: "en-GB"}];
const stub = {speaking: false, pending: false, speak(u) { window.spokenWords.push(u.text); }, cancel() {},
              getVoices() { return window.voices; }};
Object.defineProperty(window, "speechSynthesis", {value: stub, configurable: true});
if (!window.SpeechSynthesisUtterance) window.SpeechSynthesisUtterance = function (text) { this.text = text; };
true
"""


def test_the_page_shows_and_speaks_the_instruction_and_the_dose_is_published(ros_context, tmp_path):
    from rclpy.node import Node
    from test_dashboard_browser import Browser

    from gait_biofeedback.nodes.biofeedback import BiofeedbackNode
    from gait_biofeedback.nodes.common import publisher, subscribe
    from gait_biofeedback.wire import topics
    from gait_biofeedback.wire.calibration import mounting_msg

    bio = BiofeedbackNode(ros_context, port=0, stride_wait_s=0.0, feedback_schedule="bandwidth",
                          words_every=1)
    source = Node("hand_made_inputs", context=ros_context)
    cycles, calibration = (publisher(source, t) for t in (topics.GAIT_CYCLES, topics.CALIBRATION))
    given = []
    subscribe(source, topics.GIVEN, given.append)
    with spinning_in_background(ros_context, bio, source), \
            contextlib.closing(Browser(bio.server.url, 1280, 800)) as browser:
        browser.wait_for(lambda s: s.get("connected") and s.get("hello"), timeout=15)
        assert browser.evaluate(STUB_SPEECH) is True
        cycles.publish(_cycle("left", 1, 10.0))  # before a calibration: no feedback
        assert _until(browser, "stat-strides", lambda t: t == "1 / 0") == "1 / 0"
        assert browser.evaluate("document.getElementById('instruction').hidden") is True
        calibration.publish(mounting_msg({"left_foot": [1.0, 0, 0, 0], "right_foot": [1.0, 0, 0, 0]}, 0,
                                         "walking", "explained_variance"))
        browser.wait_for(lambda s: (s.get("calibrationInForce") or {}).get("valid"), timeout=10)

        cycles.publish(_cycle("right", 1, 10.75))
        state = browser.wait_for(lambda s: s.get("instructionsReceived", 0) >= 1, timeout=10)
        assert _text(browser, "instruction-text") == "Take quicker steps"
        detail = _text(browser, "instruction-detail")
        assert detail == ("Cadence: measured 80 steps/min, target 96 steps/min to 126 steps/min "
                          "(feedback: only outside the target range)"), detail
        assert browser.evaluate("window.spokenWords") == ["Take quicker steps"] and state["spoken"] == 1
        deadline = time.monotonic() + 5
        while not given and time.monotonic() < deadline:
            time.sleep(0.05)
        assert [(g.rule, g.text, g.quantity, g.schedule, g.kind) for g in given] == \
            [("quicker_steps", "Take quicker steps", "cadence", "bandwidth", 1)]
        assert abs(given[0].measured * 60 - 80) < 1e-9 and given[0].band_low * 60 == pytest.approx(96)
        shots = _fits(browser, tmp_path, "instruction")  # 1280x800 and 1024x768: no scrolling, no clipping
        browser.call("Emulation.setDeviceMetricsOverride", width=1280, height=800, deviceScaleFactor=1,
                     mobile=False)

        # muted: shown, not spoken
        browser.evaluate("document.getElementById('mute').click()")
        browser.wait_for(lambda s: s.get("muted"), timeout=5)
        cycles.publish(_cycle("left", 2, 11.5))
        state = browser.wait_for(lambda s: s.get("instructionsReceived", 0) >= 2, timeout=10)
        assert state["spoken"] == 1 and browser.evaluate("window.spokenWords.length") == 1
        assert _text(browser, "instruction-text") == "Take quicker steps"

        # sound on, no voice: the fallback tones instead of words
        browser.evaluate("window.voices = []; document.getElementById('mute').click()")
        browser.wait_for(lambda s: not s.get("muted"), timeout=5)
        cycles.publish(_cycle("right", 2, 12.25))
        state = browser.wait_for(lambda s: s.get("instructionsReceived", 0) >= 3, timeout=10)
        assert (state["spoken"], state["toneFallbacks"]) == (1, 1)

        # the therapist feeds back the knee only: cadence gives no instruction any more
        browser.evaluate("const j = document.getElementById('joint'); j.value = 'knee';"
                         "j.dispatchEvent(new Event('change')); true")
        browser.wait_for(lambda s: (s.get("lastReply") or {}).get("action") == "feedback", timeout=5)
        cycles.publish(_cycle("left", 3, 13.0))
        assert _until(browser, "stat-strides", lambda t: t == "3 / 2") == "3 / 2"
        time.sleep(0.3)  # a frame or two after the stride's
        assert browser.state()["instructionsReceived"] == 3 and len(given) == 3
        print("\nscreenshots:\n" + "\n".join(shots))

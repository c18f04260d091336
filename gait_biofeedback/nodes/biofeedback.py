"""Node ``biofeedback``: per-stride comparison with the therapist's targets, cues, and the live dashboard.

Thesis ch. 8 and §9.2.5 (gait.md §5.3): the stick figure and joint-angle graphs for patient and therapist,
and the prescriptive layer (measured vs targeted pattern → visual and auditory cues); the rules are in
:mod:`gait_biofeedback.core.biofeedback.evaluator`.

Subscribes ``joint_states`` (sensor_msgs/JointState, rad), ``gait/cycles`` (GaitCycle), ``gait/events``
(GaitEvent), ``activity/state`` (ActivityState) and ``/diagnostics``. At each plausible stride it waits
until the joint angles reach the closing IC (at most ``stride_wait_s`` s, then the kinematic quantities are
left out) and publishes one ``biofeedback/cues`` (BiofeedbackCue) per targeted quantity, in band or not.
Joint states marked as recovering from a sensor dropout (:mod:`gait_biofeedback.wire.joints`) are
shown, marked, but never evaluated: a stride that contains them gets no kinematic cue.

Dashboard (``serve_dashboard``): :class:`~gait_biofeedback.dashboard.server.DashboardServer` on
``host``:``port`` (127.0.0.1:8080; port 0 = a free port, see :attr:`BiofeedbackNode.port`), page at
``/``, websocket at ``/ws``, frames at ``frame_rate_hz`` Hz built from the latest state. ROS callbacks only
replace references and append to bounded deques; the server thread only reads/drains them. Page → node
messages (queued, handled by a ROS timer, services called with ``call_async``, never blocking):
``{"action": "calibrate", "protocol": "auto"|"hip_flexion"|"walking"}`` (default auto: the one the movement
shows) → ``calibration/calibrate`` (the reply adds ``looks_like``, which the page proposes after a refusal);
``{"action": "record_start"}`` / ``"record_stop"`` → ``recorder/start`` / ``recorder/stop``;
``{"action": "feedback", "side": "left"|"right"|"both", "joint":
"hip"|"knee"|"ankle"|"timing"|"spatial"|"all"}``;
``{"action": "mute", "muted": bool}``. Replies: ``{"type": "reply", "action", "success", "message"}``.

Audio: the cue to sound (largest error of the chosen side/joint among the latest cues, silent when all
are in band, and silent before a calibration is in force: "not calibrated yet: no feedback") is sent
to the page as ``{"type": "audio", "frequency", "rate", ...}``; the page beeps with
WebAudio, so the robot side needs no sound hardware. Cues and the sounded one carry their advice in a
clinician's words (:mod:`~gait_biofeedback.core.biofeedback.advice`); the tone stays a detail.

Each evaluated stride goes to the page as one ``{"type": "spatial", ..., "values": {quantity: value}}``
(every quantity, null when the stride has none): the Gait panel and the Targets table both read the
values of the latest stride from it, so they cannot disagree. When the node stops, the page gets
``{"type": "end"}`` and keeps the last values on screen under "session ended".

Parameters: :class:`~gait_biofeedback.core.biofeedback.evaluator.BiofeedbackParams` (the body
dimensions draw the stick figure).
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections import deque
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.context import Context
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from gait_biofeedback.core.biofeedback.advice import advice, quantity_label
from gait_biofeedback.core.biofeedback.evaluator import (
    DASHBOARD_LINK_FILE,
    QUANTITIES,
    SPATIAL,
    BiofeedbackEvaluator,
    BiofeedbackParams,
    Cue,
    Stride,
    StrideResult,
    default_targets_path,
    load_targets,
    sagittal_stick_figure,
    select_audio_cue,
)
from gait_biofeedback.core.calibration.sensor_to_segment import AUTO, REQUESTS
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.core.stamps import NS_PER_S
from gait_biofeedback.dashboard.commands import CommandError, parse_command
from gait_biofeedback.nodes.common import GuardedNode, publisher, subscribe
from gait_biofeedback.nodes.parameters import declare_parameters, node_overrides
from gait_biofeedback.wire import diagnostics, topics
from gait_biofeedback.wire.activity import state_of
from gait_biofeedback.wire.biofeedback import cue_msg
from gait_biofeedback.wire.gait import event_of, foot_frame, stride_of
from gait_biofeedback.wire.joints import angles_of, recovering_of
from gait_biofeedback.wire.stamps import stamp_to_ns
from gait_biofeedback_msgs.msg import ActivityState, GaitCycle, GaitEvent, SegmentCalibrationArray
from gait_biofeedback_msgs.srv import Calibrate

_LOCOMOTION_TEXT = {"level": "level walking"}
_SAMPLE_NAMES = tuple(f"{side}_{name}" for side in SIDES
                      for name in ("hip_flexion", "knee_flexion", "ankle_dorsiflexion"))


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _drain(queue: deque) -> list:
    """Everything in a deque another thread appends to, oldest first (popleft is thread-safe)."""
    out = []
    while True:
        try:
            out.append(queue.popleft())
        except IndexError:
            return out


def cue_to_json(c: Cue, stride_side: str = "") -> dict[str, Any]:
    """A cue for the page (SI; NaN → null), with its words; ``stride_side``: the side of the stride it
    comes from (a bilateral cue has side "")."""
    return {"type": "cue", "quantity": c.quantity, "side": c.side, "unit": c.unit,
            "label": quantity_label(c.quantity, c.side), "advice": advice(c),
            "stride_side": stride_side or c.side,
            "measured": _finite(c.measured), "low": c.band_low, "high": c.band_high,
            "error": _finite(c.error), "severity": c.severity,
            "frequency": c.audio_frequency, "rate": c.audio_rate, "stride": c.stride_index,
            "t": c.stamp_ns / NS_PER_S}


class BiofeedbackNode(GuardedNode):
    """Biofeedback cues and the dashboard server (see module docstring)."""

    NODE_NAME = "biofeedback"

    def __init__(self, context: Context | None = None, params: BiofeedbackParams | None = None,
                 **overrides: object) -> None:
        super().__init__(self.NODE_NAME, context=context, parameter_overrides=node_overrides(overrides))
        self.params: BiofeedbackParams = declare_parameters(self, BiofeedbackParams, params)
        p = self.params
        self.targets = load_targets(p.targets_file or str(default_targets_path()))
        self.targets_json = self.targets.to_json()
        self.stride_wait_s = p.stride_wait_s
        self.curve_strides = p.curve_strides
        self.feedback = {"side": p.feedback_side, "joint": p.feedback_joint}
        self.lengths = p.body
        self.evaluator = BiofeedbackEvaluator(self.targets, lengths=self.lengths)
        self.muted = False
        # state shared with the server thread: references replaced whole, bounded deques
        self._latest: tuple[float, dict[str, float], tuple[str, ...]] | None = None
        self._latest_sent: float | None = None
        self._samples: deque[list[float]] = deque(maxlen=500)
        self._outbox: deque[dict[str, Any]] = deque(maxlen=5000)
        self._commands: deque[dict[str, Any]] = deque(maxlen=100)
        self._recent_strides: deque[dict[str, Any]] = deque(maxlen=2 * max(self.curve_strides, 1))
        self._activity: dict[str, Any] | None = None
        self._calibration: dict[str, Any] | None = None  # the one in force, for the page
        self._sent_calibration: dict[str, Any] | None = None
        self._activity_version = 0
        self._sent_activity_version = -1
        self._diag: dict[str, dict[str, Any]] = {}
        self._diag_version = 0
        self._sent_diag_version = -1
        self._last_diag_sent = 0.0
        self._audio: dict[str, Any] = {"type": "audio", "frequency": 0.0, "rate": 0.0, "severity": 0,
                                       "quantity": "", "side": "", "calibrated": False}
        self._latest_cues: dict[tuple[str, str], Cue] = {}
        self._pending: list[tuple[Stride, float]] = []
        self._seq = 0
        self.counts = {"joint_states": 0, "recovering_joint_states": 0, "strides": 0,
                       "strides_without_angles": 0, "implausible": 0, "cues": 0, "frames": 0, "commands": 0}
        self._index_names: tuple[str, ...] = ()
        self._index: list[int | None] = []

        for topic, callback in ((topics.JOINT_STATES, self._on_joints), (topics.GAIT_CYCLES, self._on_cycle),
                                (topics.GAIT_EVENTS, self._on_event), (topics.ACTIVITY, self._on_activity),
                                (topics.DIAGNOSTICS, self._on_diagnostics),
                                (topics.CALIBRATION, self._on_calibration)):
            subscribe(self, topic, callback)
        self._cues = publisher(self, topics.CUES)
        self._calibrate = self.create_client(Calibrate, topics.CALIBRATE_SERVICE)
        self._record = {"record_start": self.create_client(Trigger, topics.RECORDER_START_SERVICE),
                        "record_stop": self.create_client(Trigger, topics.RECORDER_STOP_SERVICE)}
        self.create_timer(0.05, self._tick)
        self.create_timer(p.diagnostics_period_s, self._publish_diagnostics)

        self.server = None
        self.port: int | None = None
        self.url_file: Path | None = None
        if p.serve_dashboard:
            from gait_biofeedback.dashboard.server import DashboardServer

            self.server = DashboardServer(self.build_frame, self._commands.append, self.hello, host=p.host,
                                          port=p.port, frame_rate_hz=p.frame_rate_hz,
                                          logger=self.get_logger(), allowed_hosts=p.allowed_hosts)
            self.port = self.server.start()
            self.url_file = write_private_link(self.server.url, p.session_dir)
            # the token goes to the terminal and an owner-only file, never to rclpy's log (/rosout, log files)
            print(f"dashboard: {self.server.url}  (commands need this link; without its token the page is "
                  "a read-only view)" + (f"; also in {self.url_file}" if self.url_file else ""), flush=True)
            page = self.server.url.partition("?")[0]
            self.get_logger().info(f"dashboard: {page} (read-only view; the link with the command token was "
                                   "printed on the terminal" + (f" and written to {self.url_file})"
                                                                if self.url_file else ")"))

    # -- ROS callbacks (executor thread): cheap, never wait ------------------------------------------

    def _on_joints(self, msg: JointState) -> None:
        names = msg.name
        if tuple(names) != self._index_names:
            self._index_names = tuple(names)
            lookup = {n: i for i, n in enumerate(names)}
            self._index = [lookup.get(n) for n in _SAMPLE_NAMES]
        pos = msg.position
        stamp_ns, angles = angles_of(msg)
        t = stamp_ns / NS_PER_S
        self.counts["joint_states"] += 1
        recovering = recovering_of(msg)
        self._latest = (t, angles, recovering)
        row = [t] + [float(pos[i]) if i is not None else math.nan for i in self._index]
        self._samples.append(row)
        self.counts["recovering_joint_states"] += bool(recovering)
        for k, side in enumerate(SIDES):
            hip, knee, ankle = row[1 + 3 * k: 4 + 3 * k]
            if not (math.isnan(hip) or math.isnan(knee) or math.isnan(ankle)):
                self.evaluator.add_angles(side, stamp_ns, hip, knee, ankle, doubtful=bool(recovering))
        if self._pending:
            self._process_pending()

    def _on_cycle(self, msg: GaitCycle) -> None:
        stride = stride_of(msg)
        self._outbox.append({"type": "cycle", "side": stride.side, "stride": stride.index, "t": stride.t_end,
                             "stance_fraction": _finite(stride.stance_fraction),
                             "cadence": _finite(stride.cadence),
                             "symmetry": _finite(stride.step_time_symmetry),
                             "stride_time": _finite(float(msg.stride_time)), "plausible": stride.plausible,
                             "flag": msg.flag, "spatial_flag": msg.spatial_flag})
        if not stride.plausible:
            self.counts["implausible"] += 1
            return
        self._pending.append((stride, time.monotonic()))
        self._process_pending()

    def _on_event(self, msg: GaitEvent) -> None:
        side, kind, stamp_ns, index = event_of(msg)
        self._outbox.append({"type": "event", "side": side, "kind": kind.upper(), "t": stamp_ns / NS_PER_S,
                             "index": index, "flag": msg.flag})

    def _on_activity(self, msg: ActivityState) -> None:
        state = state_of(msg)
        transition = state["last_transition"]
        self._activity = {"posture": state["posture"],
                          "locomotion": _LOCOMOTION_TEXT.get(state["locomotion"], state["locomotion"]),
                          "last_transition": transition.replace("_", " ") if transition else "none",
                          "step_count": state["step_count"], "trunk_inclination": state["trunk_inclination"],
                          "t": state["stamp_ns"] / NS_PER_S}
        self._activity_version += 1

    def _on_calibration(self, msg: SegmentCalibrationArray) -> None:
        valid = [e.segment for e in msg.segments if e.valid]
        computed = stamp_to_ns(msg.computed_at)
        self._calibration = {"protocol": msg.protocol, "source": msg.source or "unknown source",
                             "computed_at": computed / NS_PER_S if computed else None,
                             "in_force_from": stamp_to_ns(msg.header.stamp) / NS_PER_S,
                             "valid": valid, "segments": len(msg.segments)}
        self._update_audio()

    @property
    def calibrated(self) -> bool:
        """A calibration with at least one valid segment is in force (joint angles can follow)."""
        return bool(self._calibration and self._calibration["valid"])

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for s in msg.status:
            level = diagnostics.level_of(s)
            self._diag[s.name] = {"name": s.name, "level": int(level), "message": s.message,
                                  "hardware_id": s.hardware_id,
                                  "values": {kv.key: kv.value for kv in s.values}}
        self._diag_version += 1

    def _tick(self) -> None:
        if self._pending:
            self._process_pending()
        while self._commands:
            try:
                command = self._commands.popleft()
            except IndexError:
                break
            self.counts["commands"] += 1
            self._handle(command)

    # -- strides → cues -------------------------------------------------------------------------------

    def _process_pending(self) -> None:
        now = time.monotonic()
        keep = []
        for stride, arrived in self._pending:
            if self.evaluator.covers(stride) or now - arrived > self.stride_wait_s:
                self._evaluate(stride)
            else:
                keep.append((stride, arrived))
        self._pending = keep

    def _evaluate(self, stride: Stride) -> None:
        result: StrideResult = self.evaluator.evaluate(stride)
        self.counts["strides"] += 1
        if not result.curves:
            self.counts["strides_without_angles"] += 1
        doubtful = bool(stride.spatial_flag) or not stride.plausible
        measured = {"stance_fraction": stride.stance_fraction, "cadence": stride.cadence,
                    "step_time_symmetry": stride.step_time_symmetry, **result.kinematics, **result.spatial}
        values = {q: _finite(measured.get(q, math.nan)) for q in QUANTITIES}
        self._outbox.append({"type": "spatial", "side": stride.side, "stride": stride.index,
                             "t": stride.t_end, "flag": stride.spatial_flag, "turning": stride.turning,
                             "turning_angle": _finite(stride.turning_angle), "values": values,
                             **{k: _finite(result.spatial.get(k, math.nan)) for k in SPATIAL},
                             **{k: None if doubtful else _finite(getattr(stride, k))
                                for k in ("max_foot_height", "foot_angle_ic")}})
        for c in result.cues:
            self._cues.publish(cue_msg(c, foot_frame(stride.side)))
            self.counts["cues"] += 1
            self._latest_cues[(c.quantity, c.side)] = c
            self._outbox.append(cue_to_json(c, stride.side))
        if result.curves:
            entry = {"type": "stride", "side": stride.side, "stride": stride.index, "t": stride.t_end,
                     "tc_percent": 100.0 * (stride.t_tc - stride.t_start) / (stride.t_end - stride.t_start),
                     "percent": result.percent.tolist(),
                     "curves": {k: [round(float(v), 5) for v in arr] for k, arr in result.curves.items()}}
            self._recent_strides.append(entry)
            self._outbox.append(entry)
        self._update_audio()

    def _update_audio(self) -> None:
        cue = (select_audio_cue(self._latest_cues.values(), self.feedback["side"], self.feedback["joint"])
               if self.calibrated else None)  # before a calibration: no feedback
        audio = {"type": "audio", "frequency": 0.0, "rate": 0.0, "severity": 0, "quantity": "", "side": "",
                 "error": 0.0, "unit": "", "calibrated": self.calibrated}
        if cue is not None:
            audio.update(frequency=cue.audio_frequency, rate=cue.audio_rate, severity=cue.severity,
                         quantity=cue.quantity, side=cue.side, error=cue.error, unit=cue.unit,
                         measured=_finite(cue.measured), low=cue.band_low, high=cue.band_high,
                         label=quantity_label(cue.quantity, cue.side), advice=advice(cue))
        shown = ("frequency", "rate", "quantity", "side", "calibrated", "measured")  # the page shows each
        if any(audio.get(k) != self._audio.get(k) for k in shown):
            self._audio = audio
            self._outbox.append(dict(audio))

    # -- page commands (executor thread, via the queue) -----------------------------------------------

    def _reply(self, action: str, success: bool, message: str, **extra: Any) -> None:
        self._outbox.append({"type": "reply", "action": action, "success": bool(success), "message": message,
                             **extra})

    def _handle(self, command: dict[str, Any]) -> None:
        try:
            action, fields = parse_command(command)
        except CommandError as exc:
            self._reply(str(command.get("action", "?"))[:40], False, str(exc))
            return
        if action == "calibrate":
            protocol = fields.get("protocol", AUTO)
            if not self._calibrate.service_is_ready():
                self._reply(action, False,
                            "calibration service not available: is the calibration node running?")
                return
            request = Calibrate.Request(protocol=protocol,
                                        standing_duration=fields.get("standing_duration", 0.0),
                                        motion_duration=fields.get("motion_duration", 0.0))
            self._reply(action, True, f"calibrating ({protocol}) ...", pending=True)
            future = self._calibrate.call_async(request)
            future.add_done_callback(self.guarded("calibrate reply", lambda f: self._service_done(action, f)))
        elif action in self._record:
            client = self._record[action]
            if not client.service_is_ready():
                self._reply(action, False, "recorder service not available: is the recorder node running?")
                return
            future = client.call_async(Trigger.Request())
            future.add_done_callback(self.guarded(f"{action} reply", lambda f: self._service_done(action, f)))
        elif action == "feedback":
            self.feedback = {"side": fields.get("side", self.feedback["side"]),
                             "joint": fields.get("joint", self.feedback["joint"])}
            self._reply(action, True, f"feedback on {self.feedback['side']} / {self.feedback['joint']}",
                        feedback=dict(self.feedback))
            self._update_audio()
        else:  # mute
            self.muted = fields.get("muted", not self.muted)
            self._reply(action, True, "muted" if self.muted else "sound on", muted=self.muted)

    def _service_done(self, action: str, future: Any) -> None:
        try:
            response = future.result()
        except Exception as exc:
            self._reply(action, False, f"{action} failed: {exc}")
            return
        if response is None:
            self._reply(action, False, f"{action}: no response")
            return
        extra = {}
        if action == "calibrate":
            extra["segments"] = [{"segment": s.segment, "valid": bool(s.valid), "quality": float(s.quality),
                                  "message": s.message} for s in response.segments]
            extra["looks_like"] = response.looks_like
        self._reply(action, bool(response.success), response.message, **extra)

    # -- server thread: hello and frames (read/drain only) -------------------------------------------

    def hello(self) -> dict[str, Any]:
        """First message to a page: targets, reference curves, feedback choice, recent strides."""
        # the new page gets the full diagnostics and activity with the next frame
        self._sent_diag_version = -1
        self._sent_activity_version = -1
        return {"type": "hello", "targets": self.targets_json, "feedback": dict(self.feedback),
                "muted": self.muted, "protocols": list(REQUESTS), "audio": dict(self._audio),
                "strides": list(self._recent_strides), "calibration": self._calibration, "time": time.time()}

    def build_frame(self) -> dict[str, Any] | None:
        """One websocket frame: new samples, latest angles and stick figure, queued messages, state."""
        frame: dict[str, Any] = {"type": "frame"}
        samples = _drain(self._samples)
        if samples:
            frame["samples"] = [[round(v, 5) if not math.isnan(v) else None for v in row] for row in samples]
        latest = self._latest
        if latest is not None and latest[0] != self._latest_sent:
            t, angles, recovering = latest
            self._latest_sent = t
            frame["angles"] = {"t": t, "values": {k: float(v) for k, v in angles.items()},
                               "recovering": list(recovering)}
            frame["figure"] = [[seg, round(x0, 4), round(y0, 4), round(x1, 4), round(y1, 4)]
                               for seg, x0, y0, x1, y1 in sagittal_stick_figure(angles, self.lengths)]
        messages = _drain(self._outbox)
        if messages:
            frame["messages"] = messages
        if self._activity_version != self._sent_activity_version and self._activity is not None:
            self._sent_activity_version = self._activity_version
            frame["activity"] = self._activity
        calibration = self._calibration  # replaced whole by the executor thread
        if calibration is not self._sent_calibration:
            self._sent_calibration = calibration
            frame["calibration"] = calibration
        now = time.monotonic()
        if self._diag_version != self._sent_diag_version and now - self._last_diag_sent >= 0.5:
            self._sent_diag_version = self._diag_version
            self._last_diag_sent = now
            frame["diagnostics"] = list(self._diag.values())
        if len(frame) == 1:
            return None
        self._seq += 1
        self.counts["frames"] += 1
        frame["seq"] = self._seq
        frame["wall"] = time.time()
        return frame

    # -- diagnostics and shutdown --------------------------------------------------------------------

    def _publish_diagnostics(self) -> None:
        values: dict[str, Any] = dict(self.counts)
        level, text = DiagnosticStatus.OK, "comparing strides with the targets"
        if self.server is not None:
            values.update(port=self.port, clients=self.server.clients, frames_sent=self.server.frames_sent,
                          frames_skipped=self.server.frames_skipped)
            if self.server.error is not None:
                level, text = DiagnosticStatus.ERROR, f"dashboard server failed: {self.server.error}"
        if level == DiagnosticStatus.OK and self.counts["joint_states"] == 0:
            level, text = DiagnosticStatus.WARN, "no joint angles yet: calibrate, then walk"
        self.publish_diagnostics([diagnostics.status("biofeedback", level, text, values=values)])

    def destroy_node(self) -> None:
        if self.server is not None:
            latest = self._latest
            self.server.stop(final={"type": "end", "wall": time.time(),
                                    "t": latest[0] if latest is not None else None})
            self.server = None
        if self.url_file is not None:  # the token dies with the server
            self.url_file.unlink(missing_ok=True)
            self.url_file = None
        super().destroy_node()



def write_private_link(url: str, session_dir: str) -> Path | None:
    """Write the dashboard's link with its command token to ``<session_dir>/dashboard_url.txt``, created
    readable and writable by its owner only (0600, whatever the umask); None when no ``session_dir``.
    The node removes it when it stops."""
    if not session_dir:
        return None
    path = Path(session_dir) / DASHBOARD_LINK_FILE
    path.parent.mkdir(parents=True, exist_ok=True)
    with contextlib.suppress(FileNotFoundError):
        path.unlink()  # a file left by an earlier session may have looser permissions
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(url + "\n")
    return path


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([BiofeedbackNode], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())

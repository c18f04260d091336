"""Node ``foxglove``: the graph served live to Foxglove (``run|replay --foxglove [PORT]``).

A Foxglove WebSocket protocol server (``foxglove.websocket.v1``, the PyPI ``foxglove-sdk``; its own
thread, outside the executor) on ``host:port`` (127.0.0.1 by default, as the dashboard), read-only: it
advertises no capability, so a viewer can neither publish, nor set parameters, nor call services.
Channels (Foxglove's well-known schemas where there is one, so the 3D and plot panels read them as is):

* ``/tf`` (foxglove.FrameTransforms): the 8 segment frames of the body
  (:mod:`~gait_biofeedback.core.joints.body_pose`, from
  :class:`~gait_biofeedback.wire.body.BodyFrameTracker`), one per ``joint_states``, at its stamp;
* ``/body`` (foxglove.SceneUpdate): a box per segment, locked to its frame; a foot is green from its
  initial contact, orange from its terminal contact (``gait/events``); sent on each event and every
  ``scene_period_s``;
* ``/joint_angles`` (JSON, ``<joint name>_deg``): the joint states in degrees, for the plot panels
  (display only: the recording keeps ``joint_states`` in rad);
* ``/gait/events``, ``/biofeedback/cues``, ``/diagnostics``: the graph's messages as they are (CDR,
  ros2msg schemas).

The work is done only while a viewer subscribes to a channel (the SDK says so): without one the node
costs the graph its subscriptions. Parameters: :class:`~gait_biofeedback.io.params.FoxgloveParams`.
Layout: ``config/foxglove_layout.json``; guide: ``docs/foxglove.md``.
"""

from __future__ import annotations

import json
import math

from rclpy.context import Context
from rclpy.serialization import deserialize_message

from gait_biofeedback.core.gait.events import INITIAL_CONTACT
from gait_biofeedback.core.joints.angles import JOINT_NAMES
from gait_biofeedback.core.joints.body_pose import BODY_FRAMES
from gait_biofeedback.io.params import FoxgloveParams
from gait_biofeedback.io.schemas import schema_text
from gait_biofeedback.nodes.common import GuardedNode, subscribe
from gait_biofeedback.nodes.parameters import declare_parameters, node_overrides
from gait_biofeedback.wire import topics
from gait_biofeedback.wire.body import INPUTS, BodyFrameTracker, BodyPose
from gait_biofeedback.wire.gait import event_of
from gait_biofeedback_msgs.msg import GaitEvent

TF_CHANNEL = "/tf"
SCENE_CHANNEL = "/body"
ANGLES_CHANNEL = "/joint_angles"
ANGLES_SCHEMA = {
    "title": "gait_biofeedback/JointAngles",
    "type": "object",
    "properties": {"stamp_ns": {"type": "integer", "description": "the joint states' stamp, ns"},
                   **{f"{name}_deg": {"type": "number", "description": f"{name}, degrees"}
                      for name in JOINT_NAMES}},
}
PASSED_ON = (topics.GAIT_EVENTS, topics.CUES, topics.DIAGNOSTICS)
"""The graph's topics served as they are (CDR with their ros2msg schema)."""
SEGMENT_COLOUR = (0.55, 0.62, 0.75, 1.0)
STANCE_COLOUR = (0.15, 0.75, 0.3, 1.0)
SWING_COLOUR = (1.0, 0.55, 0.1, 1.0)


class FoxgloveView(GuardedNode):
    """The Foxglove live view (see module docstring)."""

    NODE_NAME = "foxglove"

    def __init__(self, context: Context | None = None, params: FoxgloveParams | None = None,
                 **overrides: object) -> None:
        super().__init__(self.NODE_NAME, context=context, parameter_overrides=node_overrides(overrides))
        try:
            import foxglove
            from foxglove.channels import FrameTransformsChannel, SceneUpdateChannel
        except ImportError as err:
            raise RuntimeError(f"the Foxglove live view needs the PyPI package foxglove-sdk ({err}): "
                               "`make setup` installs it (requirements.txt)") from err

        p: FoxgloveParams = declare_parameters(self, FoxgloveParams, params)
        self.params = p
        self.tracker = BodyFrameTracker(p.body, self.resolve_topic_name)
        self.served = 0  # frame transforms sent
        self.foot_in_stance: dict[str, bool | None] = {"left": None, "right": None}
        self._fox = foxglove.Context()
        self._tf = FrameTransformsChannel(TF_CHANNEL, context=self._fox)
        self._scene = SceneUpdateChannel(SCENE_CHANNEL, context=self._fox)
        self._angles = foxglove.Channel(
            ANGLES_CHANNEL, message_encoding="json", context=self._fox,
            schema=foxglove.Schema(name=ANGLES_SCHEMA["title"], encoding="jsonschema",
                                   data=json.dumps(ANGLES_SCHEMA).encode()))
        self._passed: dict[str, foxglove.Channel] = {}
        for topic in PASSED_ON:
            name = self.resolve_topic_name(topic.name)
            self._passed[name] = foxglove.Channel(
                name, message_encoding="cdr", context=self._fox,
                schema=foxglove.Schema(name=topic.type_name, encoding="ros2msg",
                                       data=schema_text(topic.type_name).encode()))
            subscribe(self, topic, lambda data, name=name: self._pass_on(name, data), raw=True)
        for topic in INPUTS:
            if topic is topics.JOINT_STATES:
                subscribe(self, topic, self._on_joint_states, raw=True)
                continue
            name = self.resolve_topic_name(topic.name)
            subscribe(self, topic, lambda data, name=name: self._track(name, data), raw=True)
        self.server = foxglove.start_server(name="gait_biofeedback", host=p.host, port=p.port,
                                            capabilities=[], context=self._fox)
        self.port = self.server.port
        self.url = f"ws://{p.host}:{self.port}"
        self.get_logger().info(f"Foxglove live view: open {self.url} in Foxglove (Open connection → "
                               "Foxglove WebSocket), layout config/foxglove_layout.json")
        self._last_stamp = 0
        self.create_timer(p.scene_period_s, self._send_scene)

    def _track(self, topic: str, data: bytes) -> None:
        """An orientation is kept only while someone watches; a calibration always."""
        if topic == self.tracker.calibration or self._tf.has_sinks():
            self.tracker.feed(topic, data)

    def _on_joint_states(self, data: bytes) -> None:
        if not (self._tf.has_sinks() or self._angles.has_sinks()):
            return
        before = self.tracker.angles
        pose = self.tracker.feed(self.tracker.joint_states, data)
        if self.tracker.angles is not before and self._angles.has_sinks():
            stamp, angles = self.tracker.angles
            self._angles.log({"stamp_ns": stamp, **{f"{k}_deg": math.degrees(v) for k, v in angles.items()}},
                             log_time=stamp)
        if pose is not None:
            self._last_stamp = pose.ns
            self._tf.log(_frame_transforms(pose), log_time=pose.ns)
            self.served += 1

    def _pass_on(self, topic: str, data: bytes) -> None:
        channel = self._passed[topic]
        if topic.endswith(topics.GAIT_EVENTS.name):
            side, kind, _, _ = event_of(deserialize_message(data, GaitEvent))
            self.foot_in_stance[side] = kind == INITIAL_CONTACT
            self._send_scene()
        if channel.has_sinks():
            channel.log(data)

    def _send_scene(self) -> None:
        if self._scene.has_sinks():
            self._scene.log(body_scene(self.params, self.foot_in_stance, self._last_stamp))

    def destroy_node(self) -> None:
        server = getattr(self, "server", None)
        if server is not None:
            server.stop()
        super().destroy_node()


def _frame_transforms(pose: BodyPose):  # -> foxglove.messages.FrameTransforms
    from foxglove.messages import FrameTransform, FrameTransforms, Quaternion, Timestamp, Vector3

    sec, nsec = divmod(pose.ns, 1_000_000_000)
    stamp = Timestamp(sec, nsec)
    out = []
    for k, (child, parent) in enumerate(BODY_FRAMES):
        if not pose.present[k]:
            continue
        x, y, z = pose.trans[k]
        w, qx, qy, qz = pose.rot[k]
        out.append(FrameTransform(timestamp=stamp, parent_frame_id=parent, child_frame_id=child,
                                  translation=Vector3(x=x, y=y, z=z),
                                  rotation=Quaternion(x=qx, y=qy, z=qz, w=w)))
    return FrameTransforms(transforms=out)


Box = tuple[tuple[float, float, float], tuple[float, float, float]]


def segment_boxes(p: FoxgloveParams) -> dict[str, Box]:
    """Segment → (centre, size) m of its box in its own frame (x anterior, y proximal, z right)."""
    f, a = p.foot_length_m, p.ankle_height_m
    boxes = {"pelvis": ((0.0, 0.0, 0.0), (0.12, 0.1, p.hip_width_m + 0.06)),
             "chest": ((0.0, p.trunk_length_m / 2, 0.0), (0.14, p.trunk_length_m, 0.28))}
    for side in ("left", "right"):
        boxes[f"{side}_thigh"] = ((0.0, -p.thigh_length_m / 2, 0.0), (0.09, p.thigh_length_m, 0.09))
        boxes[f"{side}_shank"] = ((0.0, -p.shank_length_m / 2, 0.0), (0.07, p.shank_length_m, 0.07))
        boxes[f"{side}_foot"] = ((f / 2 - 0.025, 0.025 - a, 0.0), (f + 0.05, 0.05, 0.09))
    return boxes


def body_scene(p: FoxgloveParams, foot_in_stance: dict[str, bool | None], stamp_ns: int):
    """The body's SceneUpdate: one entity per segment, locked to its frame; feet coloured by phase."""
    from foxglove.messages import (
        Color,
        CubePrimitive,
        Pose,
        Quaternion,
        SceneEntity,
        SceneUpdate,
        Timestamp,
        Vector3,
    )

    stamp = Timestamp(*divmod(stamp_ns, 1_000_000_000))
    entities = []
    for segment, (centre, size) in segment_boxes(p).items():
        colour = SEGMENT_COLOUR
        side = segment.removesuffix("_foot")
        if segment.endswith("_foot") and foot_in_stance.get(side) is not None:
            colour = STANCE_COLOUR if foot_in_stance[side] else SWING_COLOUR
        cube = CubePrimitive(pose=Pose(position=Vector3(x=centre[0], y=centre[1], z=centre[2]),
                                       orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)),
                             size=Vector3(x=size[0], y=size[1], z=size[2]),
                             color=Color(r=colour[0], g=colour[1], b=colour[2], a=colour[3]))
        entities.append(SceneEntity(timestamp=stamp, frame_id=segment, id=segment, frame_locked=True,
                                    cubes=[cube]))
    return SceneUpdate(entities=entities)


def main(args: list[str] | None = None) -> int:
    """Console script."""
    from gait_biofeedback.nodes.common import run_nodes

    return run_nodes([FoxgloveView], args)


if __name__ == "__main__":
    import sys

    sys.exit(main())

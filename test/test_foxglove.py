"""The body's frames (/tf in recordings) and the Foxglove live view (issue 51, items 1-3).

The live test speaks the Foxglove WebSocket protocol itself, written from the published spec
(foxglove/ws-protocol, docs/spec.md, v1): subprotocol ``foxglove.websocket.v1``, which the SDK's
server (0.30) accepts only under its new name ``foxglove.sdk.v1`` (the same protocol, Foxglove's
discussion #1131; the Foxglove app and Lichtblick offer both, as this client does); the server's text
messages ``serverInfo`` and ``advertise`` (JSON, ``op``); the client's ``subscribe`` with
``subscriptions: [{id, channelId}]``; binary "Message Data": opcode 0x01, uint32 subscription id,
uint64 timestamp ns (little endian), then the payload. FrameTransforms is protobuf; the few fields
read are decoded here from the protobuf wire format (varint, 64-bit, length-delimited) with the
field numbers of foxglove's FrameTransform.proto (1 timestamp, 2 parent_frame_id, 3 child_frame_id,
4 translation, 5 rotation; Vector3 x, y, z = 1, 2, 3; Quaternion x, y, z, w = 1..4).
"""

from __future__ import annotations

import json
import math
import struct
import threading
from pathlib import Path

import numpy as np
import pytest
from conftest import rosbags_typestore, simulated_bag, true_calibration

from gait_biofeedback.core import quaternion as quat
from gait_biofeedback.core.body import BodyDimensions
from gait_biofeedback.core.joints.angles import JOINT_NAMES
from gait_biofeedback.core.joints.body_pose import BODY_FRAMES, body_transforms, world_poses

SEGMENTS8 = {child for child, _ in BODY_FRAMES}
UPRIGHT = np.array([math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0])  # segment y → world z, facing +x


def _angles(**named: float) -> np.ndarray:
    row = np.zeros((1, len(JOINT_NAMES)))
    for name, degrees in named.items():
        row[0, JOINT_NAMES.index(name)] = math.radians(degrees)
    return row


def _world(angles: np.ndarray) -> dict[str, np.ndarray]:
    pos, _ = world_poses(*body_transforms(UPRIGHT[None], angles, UPRIGHT[None])[:2])
    return {child: pos[0, k] for k, (child, _) in enumerate(BODY_FRAMES)}


def test_standing_places_every_joint_where_the_lengths_say():
    p = _world(_angles())
    # hip height = thigh + shank + ankle height (0.42 + 0.43 + 0.08); left is +y facing +x in ENU
    assert p["pelvis"] == pytest.approx([0.0, 0.0, 0.93], abs=1e-12)
    assert p["left_thigh"] == pytest.approx([0.0, 0.09, 0.93], abs=1e-12)
    assert p["right_shank"] == pytest.approx([0.0, -0.09, 0.51], abs=1e-12)
    assert p["right_foot"] == pytest.approx([0.0, -0.09, 0.08], abs=1e-12)


def test_flexions_move_the_limbs_forward_and_back_and_the_pelvis_rides_on_the_lowest_sole():
    p = _world(_angles(right_hip_flexion=90.0, left_knee_flexion=30.0))
    # the left leg stands, knee bent 30°: its toe (0.14 ahead, 0.08 below the ankle, turned with the shank)
    # is the lowest point: hip height = 0.42 + 0.43 cos 30° + 0.14 sin 30° + 0.08 cos 30°
    height = 0.42 + 0.43 * math.cos(math.radians(30)) + 0.07 + 0.08 * math.cos(math.radians(30))
    assert p["pelvis"][2] == pytest.approx(height, abs=1e-12)
    ankle_z = height - 0.42 - 0.43 * math.cos(math.radians(30))
    assert p["left_foot"] == pytest.approx([-0.43 * 0.5, 0.09, ankle_z], abs=1e-12)  # the shank goes back
    assert p["right_shank"] == pytest.approx([0.42, -0.09, height], abs=1e-12)  # hip flexion: thigh forward


def test_a_joint_without_angles_leaves_its_segment_and_those_below_it_out():
    angles = _angles()
    angles[0, JOINT_NAMES.index("left_knee_adduction")] = np.nan
    _, _, present = body_transforms(UPRIGHT[None], angles, None)
    assert {c for k, (c, _) in enumerate(BODY_FRAMES) if present[0, k]} == {
        "pelvis", "left_thigh", "right_thigh", "right_shank", "right_foot"}


def test_the_frames_rebuild_a_simulated_walk_from_its_true_angles(tmp_path):
    """Truth: the simulator's own segment positions (its rigid-link kinematics), from the true pelvis
    orientation and joint angles; lengths as simulated."""
    from gait_biofeedback.sim.simulator import SCENARIOS, simulate

    session = simulate(SCENARIOS["walk"](duration=4.0))
    cfg, truth = session.config, session.truth
    body = BodyDimensions(thigh_length_m=cfg.thigh_length, shank_length_m=cfg.shank_length,
                          hip_width_m=cfg.hip_width, ankle_height_m=cfg.ankle_height)
    angles = np.stack([truth.joint_angles[name] for name in JOINT_NAMES], axis=1)
    trans, rot, present = body_transforms(truth.segment_orientation["pelvis"], angles,
                                          truth.segment_orientation["chest"], body)
    assert present.all()
    pos, q = world_poses(trans, rot)
    for k, (segment, _) in enumerate(BODY_FRAMES):
        if segment in ("pelvis", "chest"):
            continue
        relative = pos[:, k] - pos[:, 0]
        expected = truth.segment_position[segment] - truth.segment_position["pelvis"]
        assert np.abs(relative - expected).max() < 1e-9, segment  # measured 1e-15 m
        # measured 4e-8 rad: arccos of a dot product 1 - 1e-16
        assert np.abs(quat.angle_between(q[:, k], truth.segment_orientation[segment])).max() < 1e-7, segment
    # the pelvis rides on the lowest sole point; the simulator rolls the foot over a heel 6 cm behind the
    # ankle and pins its contacts: its hip height differs by at most 11.5 mm (measured) on this walk
    assert np.abs(pos[:, 0, 2] - truth.segment_position["pelvis"][:, 2]).max() < 0.025


def test_one_instant_in_floats_is_the_array_form_of_it_and_packs_to_the_same_bytes():
    from gait_biofeedback.core.joints.body_pose import body_transforms_at
    from gait_biofeedback.wire.tf import _template, tf_message, tf_messages

    rng = np.random.default_rng(5)
    pelvis = quat.normalize(rng.normal(size=(40, 4)))
    chest = quat.normalize(rng.normal(size=(40, 4)))
    chest[3] = np.nan  # no chest at that instant
    angles = rng.uniform(-1.0, 1.0, size=(40, len(JOINT_NAMES)))
    angles[7, JOINT_NAMES.index("right_knee_flexion")] = np.nan
    angles[9, JOINT_NAMES.index("left_hip_adduction")] = np.nan
    body = BodyDimensions(thigh_length_m=0.4, foot_length_m=0.2)
    trans, rot, present = body_transforms(pelvis, angles, chest, body)
    stamps = 1_000_000_000 * np.arange(40) + 7
    bulk = tf_messages(stamps, trans, rot, present)
    for i in range(40):
        named = {n: v for n, v in zip(JOINT_NAMES, angles[i].tolist(), strict=True) if not math.isnan(v)}
        t, r, p = body_transforms_at(tuple(pelvis[i]), named, tuple(chest[i]), body)
        assert p == present[i].tolist()
        assert np.array(t)[p] == pytest.approx(trans[i][p], abs=1e-12)
        assert np.array(r)[p] == pytest.approx(rot[i][p], abs=1e-12)
        one = tf_message(int(stamps[i]), t, r, p)
        doubles = [slice(at, at + 56) for _, _, at in _template(sum(1 << k for k in range(8) if p[k]))[1]]
        assert len(one) == len(bulk[i])
        assert _blank(one, doubles) == _blank(bulk[i], doubles)  # stamps, names, counts, padding
        for cut in doubles:  # the two forms round differently in the last bit
            expected = np.frombuffer(bulk[i][cut], "<f8")
            assert np.frombuffer(one[cut], "<f8") == pytest.approx(expected, abs=1e-12)


def _blank(data: bytes, cuts: list[slice]) -> bytes:
    out = bytearray(data)
    for cut in cuts:
        out[cut] = bytes(56)
    return bytes(out)


def test_tf_messages_decode_in_rosbags_and_mcap_ros2(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader

    from gait_biofeedback.io.bag import BagWriter, bag_files
    from gait_biofeedback.wire.tf import TF_TOPIC, TF_TYPE, tf_messages

    angles = np.repeat(_angles(right_hip_flexion=20.0), 3, axis=0)
    angles[1, JOINT_NAMES.index("left_ankle_inversion")] = np.nan  # one message without the left foot
    trans, rot, present = body_transforms(np.tile(UPRIGHT, (3, 1)), angles, np.tile(UPRIGHT, (3, 1)))
    stamps = [1_700_000_000_000_000_001, 1_700_000_000_010_000_001, 1_700_000_000_020_000_001]
    with BagWriter(tmp_path / "bag") as writer:
        writer.write_many([(s, TF_TOPIC, TF_TYPE, data, True)
                           for s, data in zip(stamps, tf_messages(stamps, trans, rot, present), strict=True)])
    with AnyReader([tmp_path / "bag"], default_typestore=rosbags_typestore()) as reader:
        by_rosbags = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()]
    by_mcap = []
    for file in bag_files(tmp_path / "bag"):
        with open(file, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            by_mcap += [decoded for _, _, _, decoded in reader.iter_decoded_messages()]
    for msgs in (by_rosbags, by_mcap):
        assert [len(m.transforms) for m in msgs] == [8, 7, 8]
        first = {t.child_frame_id: t for t in msgs[0].transforms}
        assert {c: first[c].header.frame_id for c in first} == dict(BODY_FRAMES)
        assert first["pelvis"].header.stamp.sec == 1_700_000_000 and first["pelvis"].header.stamp.nanosec == 1
        thigh = first["right_thigh"].transform
        assert (thigh.translation.x, thigh.translation.y, thigh.translation.z) == (0.0, 0.0, 0.09)
        half = math.radians(20.0) / 2  # hip flexion about the pelvis z (right)
        assert (thigh.rotation.w, thigh.rotation.z) == pytest.approx((math.cos(half), math.sin(half)),
                                                                     abs=1e-12)
        assert first["pelvis"].transform.translation.z == pytest.approx(0.93, abs=1e-12)


# ---------------------------------------------------------------- the live view, over the wire

SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")
MESSAGE_DATA = 0x01


def _protobuf_fields(buf: bytes) -> list[tuple[int, object]]:
    """(field number, value) of one protobuf message: varints as int, fixed64 as float64 bytes decoded,
    length-delimited as bytes (the protobuf encoding guide)."""
    out, pos = [], 0
    while pos < len(buf):
        key, pos = _varint(buf, pos)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, pos = _varint(buf, pos)
        elif wire == 1:
            value, pos = struct.unpack_from("<d", buf, pos)[0], pos + 8
        elif wire == 2:
            size, pos = _varint(buf, pos)
            value, pos = buf[pos:pos + size], pos + size
        elif wire == 5:
            value, pos = buf[pos:pos + 4], pos + 4
        else:
            raise ValueError(f"wire type {wire}")
        out.append((number, value))
    return out


def _varint(buf: bytes, pos: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        byte = buf[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if not byte & 0x80:
            return value, pos


def _transforms(payload: bytes) -> dict[str, tuple[str, tuple[float, ...], int]]:
    """child frame → (parent, translation x, y, z, stamp ns) of one foxglove.FrameTransforms."""
    out = {}
    for number, transform in _protobuf_fields(payload):
        assert number == 1
        fields = dict(_protobuf_fields(transform))
        stamp = dict(_protobuf_fields(fields.get(1, b"")))
        xyz = dict(_protobuf_fields(fields.get(4, b"")))  # proto3: a zero double is not written
        out[fields[3].decode()] = (fields[2].decode(), tuple(xyz.get(k, 0.0) for k in (1, 2, 3)),
                                   stamp.get(1, 0) * 1_000_000_000 + stamp.get(2, 0))
    return out


class FoxgloveClient:
    """A Foxglove WebSocket client of the spec (module docstring): it subscribes to every channel
    advertised and keeps what arrives."""

    def __init__(self) -> None:
        self.subprotocol = ""
        self.server_info: dict = {}
        self.channels: dict[int, dict] = {}
        self.messages: list[tuple[str, int, bytes]] = []  # (topic, timestamp, payload)
        self.stop = threading.Event()
        self.error: BaseException | None = None

    def run(self, url: str) -> None:
        from websockets.exceptions import ConnectionClosedOK
        from websockets.sync.client import connect

        try:
            with connect(url, subprotocols=list(SUBPROTOCOLS), open_timeout=5) as ws:
                self.subprotocol = ws.subprotocol
                by_subscription: dict[int, str] = {}
                while not self.stop.is_set():
                    try:
                        frame = ws.recv(timeout=0.2)
                    except TimeoutError:
                        continue
                    if isinstance(frame, str):
                        msg = json.loads(frame)
                        if msg["op"] == "serverInfo":
                            self.server_info = msg
                        elif msg["op"] == "advertise":
                            new = [c for c in msg["channels"] if c["id"] not in self.channels]
                            self.channels.update({c["id"]: c for c in new})
                            subscriptions = [{"id": 100 + c["id"], "channelId": c["id"]} for c in new]
                            by_subscription.update({s["id"]: self.channels[s["channelId"]]["topic"]
                                                    for s in subscriptions})
                            ws.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
                        continue
                    assert frame[0] == MESSAGE_DATA, f"opcode {frame[0]}"
                    subscription, stamp = struct.unpack_from("<IQ", frame, 1)
                    self.messages.append((by_subscription[subscription], stamp, bytes(frame[13:])))
        except ConnectionClosedOK:
            pass  # the server stopped with the graph
        except BaseException as err:  # handed to the test thread
            self.error = err


@pytest.mark.ros
@pytest.mark.timeout(20)
def test_a_foxglove_client_gets_the_channels_and_the_body_of_a_live_replay_at_the_stream_rate(tmp_path):
    from rosbags.highlevel import AnyReader

    from gait_biofeedback.core.calibration.stream import CALIBRATION_FILE, write_calibration_file
    from gait_biofeedback.graph import replay_through_graph
    from gait_biofeedback.sim.simulator import Phase, SimulationConfig

    phases = [Phase("stand", 1.5), Phase("walk", 4.5)]
    bag, session = simulated_bag(tmp_path / "in", SimulationConfig(phases=phases))
    write_calibration_file(tmp_path / "session" / CALIBRATION_FILE, true_calibration(session), "test")
    client = FoxgloveClient()
    readers: list[threading.Thread] = []

    def connect(nodes) -> None:  # on the replay's first instant: the server's port is known
        readers.append(threading.Thread(target=client.run, args=(nodes["foxglove"].url,), daemon=True))
        readers[0].start()

    result = replay_through_graph(
        bag, tmp_path / "rec", speed=1.0, timeout=15, foxglove=0, actions=[(0.0, connect)],
        nodes=["orientation_filter", "calibration", "joint_angles", "gait_events"],
        node_parameters={"calibration": {"session_dir": str(tmp_path / "session"),
                                         "reload_calibration": True},
                         "joint_angles": {"heading": "filters"}})  # all six joints from the first sample
    client.stop.set()
    readers[0].join(timeout=2)
    assert client.error is None, client.error
    assert client.subprotocol in SUBPROTOCOLS
    assert client.server_info["capabilities"] == []  # read-only: no client publish, parameters, services
    channels = {c["topic"]: c for c in client.channels.values()}
    assert {"/tf", "/body", "/joint_angles", "/gait/events", "/biofeedback/cues", "/diagnostics"} <= set(
        channels)
    tf, body = channels["/tf"], channels["/body"]
    assert (tf["encoding"], tf["schemaName"]) == ("protobuf", "foxglove.FrameTransforms")
    assert (body["encoding"], body["schemaName"]) == ("protobuf", "foxglove.SceneUpdate")
    diagnostics = channels["/diagnostics"]
    assert (diagnostics["encoding"], diagnostics["schemaName"], diagnostics["schemaEncoding"]) == (
        "cdr", "diagnostic_msgs/msg/DiagnosticArray", "ros2msg")
    assert "MSG: diagnostic_msgs/KeyValue" in diagnostics["schema"]
    assert "left_knee_flexion_deg" in json.loads(channels["/joint_angles"]["schema"])["properties"]

    bodies = [_transforms(payload) for topic, _, payload in client.messages if topic == "/tf"]
    # each segment's frames over the window the client saw, in recording time (the stream is 100 Hz):
    # a count over the span of their stamps, not a latency; the client joined ~0.3 s into the 6 s
    span_s = (max(b["pelvis"][2] for b in bodies) - min(b["pelvis"][2] for b in bodies)) * 1e-9
    rates = {s: sum(s in b for b in bodies) / span_s for s in SEGMENTS8}
    slow = {s: round(r, 1) for s, r in rates.items() if not 70.0 < r <= 101.0}
    if slow and (result.loss_note(1.0, bag) or span_s < 4.0):
        pytest.xfail(f"known load fragility: the graph lost samples ({result.loss_note(1.0, bag)}), frames "
                     f"per second {slow} over {span_s:.1f} s")
    assert not slow and span_s > 4.0, f"frames per second {slow} over {span_s:.1f} s"
    whole = [b for b in bodies if set(b) == SEGMENTS8]
    assert len(whole) > 0.8 * len(bodies)
    assert whole[-1]["left_thigh"][:2] == ("pelvis", (0.0, 0.0, -0.09))  # the constant joint offsets
    assert whole[-1]["right_foot"][:2] == ("right_shank", (0.0, -0.43, 0.0))
    angles = [json.loads(p) for t, _, p in client.messages if t == "/joint_angles"]
    assert len(angles) >= len(whole) and -90.0 < angles[-1]["left_knee_flexion_deg"] < 10.0
    # the scene: a box per segment locked to its frame; each foot green after an initial contact and
    # orange after a terminal one (the walk has both on both sides). SceneUpdate fields (foxglove's
    # SceneUpdate/SceneEntity/CubePrimitive/Color.proto): entities 2; frame_id 2, id 3, frame_locked 5,
    # cubes 8; color 3; r, g, b, a 1-4
    stance, swing = (0.15, 0.75, 0.3), (1.0, 0.55, 0.1)
    foot_colours: dict[str, set] = {"left_foot": set(), "right_foot": set()}
    for payload in (p for t, _, p in client.messages if t == "/body"):
        entities = [dict(_protobuf_fields(e)) for n, e in _protobuf_fields(payload) if n == 2]
        assert sorted(e[3].decode() for e in entities) == sorted(SEGMENTS8)
        assert all(e[2] == e[3] and e.get(5) == 1 for e in entities)
        for e in entities:
            if e[3].decode() in foot_colours:
                colour = dict(_protobuf_fields(dict(_protobuf_fields(e[8]))[3]))
                foot_colours[e[3].decode()].add(tuple(round(colour.get(k, 0.0), 3) for k in (1, 2, 3)))
    assert all({stance, swing} <= seen for seen in foot_colours.values()), foot_colours
    assert sum(t == "/gait/events" for t, _, _ in client.messages) >= 8

    # the recorder wrote the same frames as /tf, one per joint state, decoded by rosbags
    with AnyReader([tmp_path / "rec"], default_typestore=rosbags_typestore()) as recording:
        counts: dict[str, int] = {}
        for conn, _, raw in recording.messages():
            msg = recording.deserialize(raw, conn.msgtype)
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
            if conn.topic == "/tf":
                assert {t.child_frame_id for t in msg.transforms} <= SEGMENTS8
    assert counts["/tf"] == counts["/joint_states"] > 500


def test_the_layout_shows_only_what_the_view_serves_or_a_recording_holds():
    from gait_biofeedback.nodes.foxglove_view import (
        ANGLES_CHANNEL,
        ANGLES_SCHEMA,
        PASSED_ON,
        SCENE_CHANNEL,
        TF_CHANNEL,
    )
    from gait_biofeedback.wire import topics

    layout = json.loads((Path(__file__).parents[1] / "config" / "foxglove_layout.json").read_text())
    served = {TF_CHANNEL, SCENE_CHANNEL, ANGLES_CHANNEL, *(t.absolute() for t in PASSED_ON),
              topics.SKELETON.absolute()}

    def panels(node) -> list[str]:
        return [node] if isinstance(node, str) else panels(node["first"]) + panels(node["second"])

    assert sorted(panels(layout["layout"])) == sorted(layout["configById"])
    shown = set()
    for panel_id, config in layout["configById"].items():
        kind = panel_id.split("!")[0]
        if kind == "3D":
            shown |= set(config["topics"])
        elif kind == "Plot":
            for path in config["paths"]:
                topic, field = path["value"].split(".")
                assert field in ANGLES_SCHEMA["properties"], field
                shown.add(topic)
        elif kind == "RawMessages":
            shown.add(config["topicPath"])
        elif kind == "DiagnosticSummary":
            shown.add(config["topicToRender"])
    assert shown <= served, shown - served
    assert {"Plot!hip", "Plot!knee", "Plot!ankle", "3D!body"} <= set(layout["configById"])


@pytest.mark.ros
def test_a_recording_with_body_frames_replays_without_them(ros_context, tmp_path):
    """tf2_msgs has no PyPI wheel: the replayer cannot publish /tf, so it names and skips it."""
    from gait_biofeedback.io.bag import BagWriter
    from gait_biofeedback.nodes.imu_replayer import ImuReplayer
    from gait_biofeedback.wire.cdr import pack_imu
    from gait_biofeedback.wire.imu import raw_imu_values
    from gait_biofeedback.wire.tf import TF_TOPIC, TF_TYPE, tf_messages

    trans, rot, present = body_transforms(UPRIGHT[None], _angles(), UPRIGHT[None])
    with BagWriter(tmp_path / "bag") as writer:
        writer.write_serialized("/pelvis/imu/data_raw", "sensor_msgs/msg/Imu",
                                pack_imu(10, "pelvis_imu", raw_imu_values((0.0,) * 3, (0.0, 0.0, 9.81))), 10)
        writer.write_serialized(TF_TOPIC, TF_TYPE, tf_messages([10], trans, rot, present)[0], 10, padded=True)
    replayer = ImuReplayer(ros_context, bag=str(tmp_path / "bag"))
    try:
        assert replayer.skipped == {TF_TOPIC: TF_TYPE}
        assert list(replayer.topics) == ["/pelvis/imu/data_raw"]
    finally:
        replayer.destroy_node()

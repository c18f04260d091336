"""Parameters of the recording nodes: ``imu_replayer`` (a recording → topics) and ``recorder``
(topics → a recording), declared once as the stages of :mod:`gait_biofeedback.core` are."""

from __future__ import annotations

from dataclasses import dataclass

from gait_biofeedback.core.body import BodyDimensions, StickFigureDimensions
from gait_biofeedback.core.params import param, require, same_as

COMPRESSIONS = ("zstd", "lz4", "none")


@dataclass(frozen=True)
class ReplayerParams:
    """Parameters of the ``imu_replayer`` node."""

    bag: str = param("", "the recording to replay (rosbag2 folder or .mcap file)")
    speed: float = param(1.0, "replay speed factor (0 = as fast as possible)", "1", low=0.0, high=1000.0)
    loop: bool = param(False, "start again at the end (the stamps then jump back: downstream resets)")
    start_offset_s: float = param(0.0, "start this far into the recording", "s", low=0.0,
                                  high=604800.0)
    stop_offset_s: float = param(0.0, "stop this far into the recording (0 = at its end)", "s",
                                 low=0.0, high=604800.0)
    publish_clock: bool = param(False, "publish /clock with the recording's log time (for nodes with "
                                "use_sim_time: their stamps and the recorder's log times then follow it)")
    clock_period_s: float = param(0.01, "publish /clock at least this often in recording time (and at the "
                                  "start time while waiting for subscribers)", "s", low=0.001, high=1.0)
    topics: tuple[str, ...] = param((), "topics to replay (empty = all)")
    wait_for_subscribers_s: float = param(0.0, "wait this long for every topic to have a subscriber before "
                                          "starting (0 = start at once)", "s", low=0.0, high=600.0)

    def __post_init__(self) -> None:
        require(self.stop_offset_s == 0.0 or self.stop_offset_s > self.start_offset_s,
                f"parameter 'stop_offset_s' ({self.stop_offset_s:g} s) must be 0 or after 'start_offset_s' "
                f"({self.start_offset_s:g} s)")


@dataclass(frozen=True)
class RecorderParams(StickFigureDimensions):
    """Parameters of the ``recorder`` node; the body dimensions place the segment frames of ``/tf``."""

    output: str = param("", "bag folder to write ('' = recordings/session_<time>)")
    topics: tuple[str, ...] = param((), "topics to record (empty = every topic, discovered as it appears)")
    exclude: tuple[str, ...] = param((), "topics never recorded")
    split_size_bytes: int = param(0, "start a new file after this many bytes (0 = never)", "B",
                                  low=0, high=10**12)
    split_duration_s: float = param(0.0, "start a new file after this long (0 = never)", "s",
                                    low=0.0, high=604800.0)
    flush_period_s: float = param(1.0, "longest time before written messages are closed into a chunk (what a "
                                  "crash can lose)", "s", low=0.05, high=60.0)
    compression: str = param("zstd", "chunk compression", choices=COMPRESSIONS)
    discovery_period_s: float = param(0.5, "how often new topics are looked for", "s", low=0.05, high=60.0)
    autostart: bool = param(True, "record from the start (else wait for recorder/start)")
    body_frames: bool = param(True, "write the segment frames as /tf (tf2_msgs/TFMessage) beside each "
                              "joint_states, from the recorded angles and pelvis orientation (a /tf on the "
                              "network is then not recorded)")


@dataclass(frozen=True)
class FoxgloveParams(StickFigureDimensions):
    """Parameters of the ``foxglove`` node (the Foxglove live view); the body dimensions place and draw
    the segments."""

    host: str = param("127.0.0.1", "address the Foxglove WebSocket server binds (keep 127.0.0.1 unless "
                      "behind an authenticating proxy: the view has no login)")
    port: int = param(8765, "Foxglove WebSocket port (0 = any free port)", low=0, high=65535)
    trunk_length_m: float = same_as(BodyDimensions, "trunk_length_m")
    scene_period_s: float = param(1.0, "the body's 3D scene is sent again this often, for viewers that "
                                  "connect later", "s", low=0.1, high=60.0)

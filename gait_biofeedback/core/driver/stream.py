"""The driver's core: frames from the sensors → stamped samples per segment, and what to report.

:class:`DriverCore` decodes frames (:mod:`~gait_biofeedback.core.driver.protocol`), hands each
sample to its sensor's :class:`~gait_biofeedback.core.driver.sensor.SensorStream` by the
``sensors`` mapping (sensor id → segment, ``config/session.yaml``) and reports per sensor what
``/diagnostics`` shows: rate, loss, duplicates, clock offset and drift, last seen; a sensor that
sends but is not mapped, and a mapped sensor that is silent, are named with what to do.

A sensor id is bound to the source it is first heard from (a UDP sender's ``address:port``, the
serial device) for the session: samples claiming that id from any other source are dropped, counted
and named (two sources claim one id). With a session key (``frame_key_file``) only frames signed
with it (GBI2) are taken; unsigned or wrongly signed ones are refused and counted, as are signed
frames while no key is set.
"""

from __future__ import annotations

from dataclasses import dataclass

from gait_biofeedback.core.driver.protocol import (
    DeviceSample,
    FrameError,
    SignatureError,
    decode_frame,
    load_frame_key,
)
from gait_biofeedback.core.driver.sensor import SensorStream, StampedSample
from gait_biofeedback.core.notices import Notices
from gait_biofeedback.core.params import ParameterError, param, require
from gait_biofeedback.core.segments import SEGMENTS

BACKENDS = ("udp", "serial", "simulated")
MAX_FOREIGN_SOURCES = 16
"""Foreign sources counted by name per sensor; more are counted together as :data:`OTHER_SOURCES`."""
OTHER_SOURCES = "other sources"
DEFAULT_SENSORS = tuple(f"{i}:{segment}" for i, segment in enumerate(SEGMENTS))


@dataclass(frozen=True)
class DriverParams:
    """Parameters of the ``imu_driver`` node."""

    backend: str = param("udp", "where the samples come from: udp datagrams, a serial line, or the "
                         "simulator paced in real time", choices=BACKENDS)
    address: str = param("127.0.0.1", "udp: address to listen on (127.0.0.1 = this computer only; "
                         "0.0.0.0 = every network interface, for sensors on the clinic's network)")
    port: int = param(5600, "udp: port to listen on (0 = any free port; the log says which)",
                      low=0, high=65535)
    device: str = param("/dev/ttyUSB0", "serial: the serial device")
    baud: int = param(921600, "serial: line speed", "Bd", low=1200, high=20_000_000)
    scenario: str = param("demo", "simulated: the simulator's scenario (gait-biofeedback simulate)")
    sim_rate: float = param(100.0, "simulated: sampling rate", "Hz", low=10.0, high=2000.0)
    sim_loop: bool = param(True, "simulated: start the scenario again at its end (the sensors reboot)")
    sensors: tuple[str, ...] = param(DEFAULT_SENSORS, "sensor id → segment, as 'ID:SEGMENT' (the ids "
                                     "the sensors send; segments: pelvis, left_thigh, ... chest)")
    reorder_window: float = param(0.05, "how long a sample after a gap waits for the missing ones "
                                  "(reordered on the way) before they are counted lost", "s",
                                  low=0.0, high=1.0)
    clock_bin: float = param(0.5, "device time → ROS time: the least-delayed sample of each bin this long "
                             "is fitted", "s", low=0.05, high=10.0)
    clock_window: float = param(60.0, "device time → ROS time: offset and drift fitted over this long",
                                "s", low=5.0, high=3600.0)
    frame_key_file: str = param("", "file holding the session key the sensors sign their frames with "
                                "(GBI2, README: Frame format; mode 0600); '' = frames are not signed")
    stale_after: float = param(1.0, "a mapped sensor silent for this long is reported missing", "s",
                               low=0.05, high=60.0)
    diagnostics_period: float = param(1.0, "how often /diagnostics is published", "s", low=0.1, high=60.0)

    def __post_init__(self) -> None:
        self.mapping()  # refuse a malformed mapping now
        require(self.clock_bin < self.clock_window,
                f"parameter 'clock_bin' ({self.clock_bin:g} s) must be shorter than 'clock_window' "
                f"({self.clock_window:g} s)")

    def mapping(self) -> dict[int, str]:
        """Sensor id → segment; ParameterError for a malformed entry, an unknown segment, or an id or
        segment given twice."""
        out: dict[int, str] = {}
        for entry in self.sensors:
            sid, _, segment = entry.partition(":")
            if not sid.strip().isdigit() or not segment:
                raise ParameterError(f"parameter 'sensors': {entry!r} is not 'ID:SEGMENT' "
                                     "(e.g. '3:left_foot')")
            sid_value, segment = int(sid), segment.strip()
            if segment not in SEGMENTS:
                raise ParameterError(f"parameter 'sensors': {entry!r} names no segment; segments: "
                                     f"{', '.join(SEGMENTS)}")
            if sid_value > 0xFFFF:
                raise ParameterError(f"parameter 'sensors': sensor id {sid_value} is beyond 65535")
            if sid_value in out or segment in out.values():
                raise ParameterError(f"parameter 'sensors': {entry!r} maps a sensor id or a segment twice")
            out[sid_value] = segment
        return out


@dataclass(frozen=True)
class SensorReport:
    """What ``/diagnostics`` says of one sensor id: ``level`` 0 OK, 1 WARN, 2 ERROR, a message and
    the values (rate, loss, ...)."""

    name: str
    level: int
    message: str
    values: dict[str, object]


class DriverCore:
    """Frames → stamped samples, per-sensor accounting (module docstring)."""

    def __init__(self, params: DriverParams | None = None) -> None:
        self.params = p = params or DriverParams()
        self.notices = Notices()
        self.sensors = {sid: SensorStream(sid, segment, p.reorder_window, p.clock_bin, p.clock_window,
                                          self.notices)
                        for sid, segment in p.mapping().items()}
        self.unmapped: dict[int, int] = {}  # sensor id → samples received
        self.bad_frames = 0
        self.frames = 0
        self.refused: dict[str, int] = {"unsigned": 0, "wrong key": 0, "no key": 0}
        try:
            self._key = load_frame_key(p.frame_key_file) if p.frame_key_file else None
        except ValueError as err:
            raise ParameterError(f"imu_driver: parameter 'frame_key_file': {err}") from err
        if self._key is not None:
            self.notices.say("info", f"imu_driver: only frames signed with the session key of "
                             f"{p.frame_key_file} are taken")

    @property
    def signed(self) -> bool:
        """Whether a session key is set (only signed frames are taken)."""
        return self._key is not None

    def feed(self, frame: bytes, arrival_ns: int, source: str) -> list[StampedSample]:
        """One received frame (a datagram) from ``source`` (the sender's ``address:port``, the serial
        device) → the samples that go out now; a corrupt or refused frame is counted and dropped."""
        try:
            samples = decode_frame(frame, self._key)
        except SignatureError as err:
            self.refused[err.reason] += 1
            if self.refused[err.reason] == 1:
                what = ("signed frames came but no session key is set: set imu_driver's 'frame_key_file' "
                        "to the sensors' key file" if err.reason == "no key" else
                        f"a frame from {source} was refused ({err}); further ones are counted on "
                        "/diagnostics")
                self.notices.say("warn", f"imu_driver: {what}")
            return []
        except FrameError as err:
            self.bad_frames += 1
            if self.bad_frames == 1:
                self.notices.say("warn", f"imu_driver: a frame was dropped ({err}); further ones are counted "
                                 "on /diagnostics")
            return []
        return self.feed_samples(samples, arrival_ns, source)

    def feed_samples(self, samples: list[DeviceSample], arrival_ns: int, source: str) -> list[StampedSample]:
        """Decoded samples that arrived at ``arrival_ns`` from ``source`` → the samples that go out
        now. A mapped id is bound to the first source it comes from; from another it is dropped."""
        self.frames += 1
        out: list[StampedSample] = []
        for sample in samples:
            stream = self.sensors.get(sample.sensor_id)
            if stream is None:
                n = self.unmapped.get(sample.sensor_id, 0)
                if n == 0:
                    self.notices.say("warn", f"imu_driver: sensor {sample.sensor_id} sends but is not mapped "
                                     "to a segment (add 'ID:SEGMENT' to imu_driver's 'sensors' parameter)")
                self.unmapped[sample.sensor_id] = n + 1
                continue
            if stream.source is None:
                stream.source = source
                self.notices.say("info", f"imu_driver: {stream.name} is heard from {source}; samples "
                                 "claiming its id from elsewhere are dropped")
            elif source != stream.source:
                self._foreign(stream, source)
                continue
            out.extend(stream.push(sample, arrival_ns, self.frames))
        return out

    def _foreign(self, stream: SensorStream, source: str) -> None:
        """A sample for ``stream``'s id from another source than its own: counted, said once."""
        if not stream.foreign:
            self.notices.say("warn", f"imu_driver: sensor {stream.sensor_id} also sent from {source}: two "
                             f"sources claim one id; {stream.segment} stays bound to {stream.source} (heard "
                             "first) and the other's samples are dropped and counted on /diagnostics. Give "
                             "each sensor its own id; restart the driver if the sensor moved")
        if source in stream.foreign or len(stream.foreign) < MAX_FOREIGN_SOURCES:
            stream.foreign[source] = stream.foreign.get(source, 0) + 1
        else:
            stream.foreign[OTHER_SOURCES] = stream.foreign.get(OTHER_SOURCES, 0) + 1

    def expire(self, now_ns: int) -> list[StampedSample]:
        """Samples whose wait for missing ones has ended (call every few ms)."""
        out: list[StampedSample] = []
        for stream in self.sensors.values():
            out.extend(stream.expire(now_ns))
        return out

    def reports(self, now_ns: int) -> list[SensorReport]:
        """One report per mapped sensor, one per unmapped sensor id that sent, and one for the link."""
        stale_ns = self.params.stale_after * 1e9
        out = []
        for s in self.sensors.values():
            values: dict[str, object] = {
                "sensor_id": s.sensor_id, "received": s.received, "published": s.published,
                "lost": s.lost, "late": s.late, "duplicates": s.duplicates, "reboots": s.reboots,
                "clock_resets": s.clock_resets, "stamps_adjusted": s.stamps_adjusted,
                "rejected": s.rejected, "source": s.source or "",
                "foreign_samples": sum(s.foreign.values()), "rate_hz": s.rate_hz()}
            if s.last_arrival_ns is None:
                level, text = 2, (f"no data from sensor {s.sensor_id}: check that it is on, charged and "
                                  "sending to this computer")
            else:
                silent = (now_ns - s.last_arrival_ns) * 1e-9
                values["last_seen_s_ago"] = silent
                if s.clock.started and s.last_device_us is not None:
                    values["clock_offset_s"] = s.clock.offset_s(s.last_device_us)
                    values["clock_drift_ppm"] = s.clock.drift_ppm
                if silent * 1e9 > stale_ns:
                    level, text = 2, (f"sensor {s.sensor_id} silent for {silent:.1f} s: check its battery "
                                      "and radio range")
                else:
                    loss = s.lost / max(1, s.lost + s.published)
                    level = 1 if loss > 0.01 else 0
                    text = f"{s.rate_hz():.1f} Hz, {s.lost} lost ({100 * loss:.2f} %)" + (
                        ", above 1 %: move the receiver closer or reduce interference" if level else "")
                    if s.rejected:
                        text += f", {s.rejected} unconfirmed restart sample(s) rejected"
            if s.foreign:
                level = max(level, 1)
                text += "; " + _foreign_text(s)
            out.append(SensorReport(f"imu_driver: {s.segment}", level, text, values))
        for sid, n in sorted(self.unmapped.items()):
            out.append(SensorReport(f"imu_driver: sensor {sid}", 1,
                                    f"sensor {sid} sends but is not mapped to a segment: add '{sid}:SEGMENT' "
                                    "to imu_driver's 'sensors' parameter (config/session.yaml)",
                                    {"sensor_id": sid, "received": n}))
        refused = self.refused["unsigned"] + self.refused["wrong key"]
        if self.bad_frames or refused or self.refused["no key"]:
            parts = []
            if self.bad_frames:
                parts.append(f"{self.bad_frames} corrupt frame(s) dropped of "
                             f"{self.frames + self.bad_frames + refused + self.refused['no key']}")
            if refused:
                parts.append(f"{refused} frames refused: not signed with the session key")
            if self.refused["no key"]:
                parts.append(f"{self.refused['no key']} signed frames refused: no session key is set "
                             "(parameter 'frame_key_file')")
            out.append(SensorReport("imu_driver: link", 1, "; ".join(parts), {
                "bad_frames": self.bad_frames, "frames": self.frames,
                "unsigned_frames": self.refused["unsigned"],
                "wrongly_signed_frames": self.refused["wrong key"],
                "signed_frames_without_key": self.refused["no key"], "signed": self.signed}))
        return out


def _foreign_text(s: SensorStream) -> str:
    """The report's words on samples claiming ``s``'s id from other sources than its own."""
    names = sorted(s.foreign, key=s.foreign.get, reverse=True)
    shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
    return (f"sensor {s.sensor_id} also sent from {shown}: two sources claim one id "
            f"({sum(s.foreign.values())} samples dropped; bound to {s.source}, heard first)")

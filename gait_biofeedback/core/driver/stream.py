"""The driver's core: frames from the sensors → stamped samples per segment, and what to report.

:class:`DriverCore` decodes frames (:mod:`~gait_biofeedback.core.driver.protocol`), hands each
sample to its sensor's :class:`~gait_biofeedback.core.driver.sensor.SensorStream` by the
``sensors`` mapping (sensor id → segment, ``config/session.yaml``) and reports per sensor what
``/diagnostics`` shows: rate, loss, duplicates, clock offset and drift, last seen; a sensor that
sends but is not mapped, and a mapped sensor that is silent, are named with what to do.

A sensor id is bound to one source (a UDP sender's ``address:port``, the serial device): the first
that sends a confirmed chain of samples (:mod:`~gait_biofeedback.core.driver.chain`: 5 agreeing in
sequence and device time over at least 3 frames, arrived in real time). Until then each source's
samples are held (:data:`MAX_CANDIDATES` sources, :data:`HOLD_SAMPLES` samples each); the bound
source's go out in order, the others' are dropped and counted. Samples claiming a bound id from
another source are held as well, and dropped, counted and named (two sources claim one id) as soon
as the bound source sends again: while it keeps sending, no other source takes the id. Once it has
been silent for ``stale_after_s``, a source that sends a confirmed chain takes the id (re-binding,
with a warning): a sensor that comes back from a new source port after a reboot. With a session key
(``frame_key_file``) only frames signed with it (GBI2) are taken; unsigned or wrongly signed ones
are refused and counted, as are signed frames while no key is set.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from gait_biofeedback.core.driver.chain import CONFIRM_FRAMES, CONFIRM_SAMPLES, Chains, seq_diff, wait_ns
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

VENDOR_BACKENDS = ("ximu3", "ngimu", "shimmer", "dot")
BACKENDS = ("udp", "serial", "simulated", *VENDOR_BACKENDS)
MAX_CANDIDATES = 4
"""Sources per sensor id whose samples are held at once. A new one takes the place of the one heard
from longest ago that has not sent 2 agreeing samples; if none has, its samples are dropped."""
HOLD_SAMPLES = 1024
"""Samples held per source not (yet) bound (the oldest dropped first)."""
MAX_FOREIGN_SOURCES = 16
"""Foreign sources counted by name per sensor; more are counted together as :data:`OTHER_SOURCES`."""
OTHER_SOURCES = "other sources"
DEFAULT_SENSORS = tuple(f"{i}:{segment}" for i, segment in enumerate(SEGMENTS))


@dataclass(frozen=True)
class DriverParams:
    """Parameters of the ``imu_driver`` node."""

    backend: str = param("udp", "where the samples come from: udp datagrams, a serial line, the "
                         "simulator paced in real time, or a vendor's sensors (ximu3: x-io x-IMU3 through "
                         "its SDK; ngimu: x-io NGIMU over OSC on 'address':'port'; shimmer: Shimmer3 through "
                         "pyshimmer; dot: Movella DOT over Bluetooth LE; docs/connecting_sensors.md)",
                         choices=BACKENDS)
    address: str = param("127.0.0.1", "udp: address to listen on (127.0.0.1 = this computer only; "
                         "0.0.0.0 = every network interface, for sensors on the clinic's network)")
    port: int = param(5600, "udp: port to listen on (0 = any free port; the log says which)",
                      low=0, high=65535)
    device: str = param("/dev/ttyUSB0", "serial: the serial device")
    baud: int = param(921600, "serial: line speed", "Bd", low=1200, high=20_000_000)
    scenario: str = param("demo", "simulated: the simulator's scenario (gait-biofeedback simulate)")
    sim_rate_hz: float = param(100.0, "simulated: sampling rate", "Hz", low=10.0, high=2000.0)
    sim_loop: bool = param(True, "simulated: start the scenario again at its end (the sensors reboot)")
    device_rate_hz: float = param(100.0, "shimmer, dot: sampling rate set on each device (shimmer: 32768 Hz "
                                  "over a whole number, the nearest is taken; dot: 1, 4, 10, 12, 15, 20, 30 "
                                  "or 60)", "Hz", low=1.0, high=1024.0)
    shimmer_accelerometer: str = param("wide_range", "shimmer: the accelerometer streamed: the digital "
                                       "wide-range one (LSM303DLHC, range as configured on the device) or "
                                       "the analog low-noise one (KXRB5-2042, +-2 g: clips at heel strike)",
                                       choices=("wide_range", "low_noise"))
    sensors: tuple[str, ...] = param(DEFAULT_SENSORS, "sensor id → segment, as 'ID:SEGMENT' (the ids "
                                     "the sensors send; segments: pelvis, left_thigh, ... chest)")
    devices: tuple[str, ...] = param((), "vendor backends: device → segment, as 'DEVICE_ID=SEGMENT', the "
                                     "device as its vendor names it (ximu3: its serial number or its "
                                     "connection, e.g. 'tcp:192.168.1.20:7000'; ngimu: its address 'IP' or "
                                     "'IP:PORT'; shimmer: its serial port, e.g. '/dev/rfcomm0'; dot: its BLE "
                                     "address, e.g. 'D4:22:CD:00:12:34'); the segment's sensor id is the one "
                                     "'sensors' gives it")
    reorder_window_s: float = param(0.05, "how long a sample after a gap waits for the missing ones "
                                    "(reordered on the way) before they are counted lost", "s",
                                    low=0.0, high=1.0)
    clock_bin_s: float = param(0.5, "device time → ROS time: the least-delayed sample of each bin this long "
                               "is fitted", "s", low=0.05, high=10.0)
    clock_window_s: float = param(60.0, "device time → ROS time: offset and drift fitted over this long",
                                  "s", low=5.0, high=3600.0)
    frame_key_file: str = param("", "file holding the session key the sensors sign their frames with "
                                "(GBI2, docs/guide/live_sensors.md; mode 0600); '' = frames are not signed")
    stale_after_s: float = param(1.0, "a mapped sensor silent for this long is reported missing, and "
                                 "another source that sends a confirmed chain may then take its id", "s",
                                 low=0.05, high=60.0)
    diagnostics_period_s: float = param(1.0, "how often /diagnostics is published", "s", low=0.1, high=60.0)

    def __post_init__(self) -> None:
        self.mapping()  # refuse a malformed mapping now
        self.device_ids()
        if self.backend in VENDOR_BACKENDS:
            require(bool(self.devices), f"backend '{self.backend}' needs parameter 'devices': each device as "
                    "'DEVICE_ID=SEGMENT' (docs/connecting_sensors.md)")
            require(not self.frame_key_file, f"parameter 'frame_key_file' signs our own frames; backend "
                    f"'{self.backend}' takes the vendor's, which are not signed (they are bound to their "
                    "device instead): leave it empty")
        require(self.clock_bin_s < self.clock_window_s,
                f"parameter 'clock_bin_s' ({self.clock_bin_s:g} s) must be shorter than 'clock_window_s' "
                f"({self.clock_window_s:g} s)")

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

    def device_ids(self) -> dict[str, int]:
        """Vendor device id → the sensor id of its segment (``devices`` and ``sensors``); ParameterError
        for a malformed entry, an unknown or unmapped segment, or a device or segment given twice."""
        ids = {segment: sid for sid, segment in self.mapping().items()}
        out: dict[str, int] = {}
        for entry in self.devices:
            device, _, segment = entry.rpartition("=")
            device, segment = device.strip(), segment.strip()
            if not device or not segment:
                raise ParameterError(f"parameter 'devices': {entry!r} is not 'DEVICE_ID=SEGMENT' "
                                     "(e.g. '/dev/rfcomm0=left_shank')")
            if segment not in SEGMENTS:
                raise ParameterError(f"parameter 'devices': {entry!r} names no segment; segments: "
                                     f"{', '.join(SEGMENTS)}")
            if segment not in ids:
                raise ParameterError(f"parameter 'devices': {entry!r}: {segment} has no sensor id in "
                                     "'sensors' (add 'ID:SEGMENT' there)")
            if device in out or ids[segment] in out.values():
                raise ParameterError(f"parameter 'devices': {entry!r} maps a device or a segment twice")
            out[device] = ids[segment]
        return out


class _Candidate:
    """A source not bound to a sensor id: its held samples (sample, arrival ns, frame), its chains,
    the first sample and µs per sample of its confirmed chain (None before), until when it is kept
    once confirmed (:func:`~gait_biofeedback.core.driver.chain.wait_ns`)."""

    def __init__(self) -> None:
        self.held: deque[tuple[DeviceSample, int, int]] = deque()
        self.chains = Chains()
        self.root: DeviceSample | None = None
        self.period_us: float | None = None
        self.until_ns = 0
        self._frame, self._in_frame = 0, 0

    def heard(self, arrival_ns: int, frame: int) -> None:
        """A sample came in ``frame``: kept until its next frame is due, and a while."""
        self._in_frame = self._in_frame + 1 if frame == self._frame else 1
        self._frame = frame
        self.until_ns = wait_ns(arrival_ns, self._in_frame, self.period_us)


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
        self.sensors = {sid: SensorStream(sid, segment, p.reorder_window_s, p.clock_bin_s, p.clock_window_s,
                                          self.notices)
                        for sid, segment in p.mapping().items()}
        self.unmapped: dict[int, int] = {}  # sensor id → samples received
        self.bad_frames = 0
        self.frames = 0
        self.refused: dict[str, int] = {"unsigned": 0, "wrong key": 0, "no key": 0}
        self.rebinds = dict.fromkeys(self.sensors, 0)
        self._candidates: dict[int, dict[str, _Candidate]] = {sid: {} for sid in self.sensors}
        self._stale_ns = round(p.stale_after_s * 1e9)
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

    @property
    def frame_key(self) -> bytes | None:
        """The session key (read once, at start), for the simulator to sign with; never to be shown."""
        return self._key

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
        now. A mapped id's samples from its bound source go to its stream, others are held (module
        docstring)."""
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
            elif source == stream.source:
                pending = self._candidates[stream.sensor_id]
                if pending:  # the bound source goes on: the others only claimed its id
                    self._drop_all(stream, pending)
                out.extend(stream.push(sample, arrival_ns, self.frames))
            else:
                out.extend(self._hold(stream, sample, arrival_ns, source))
        return out

    def _hold(self, stream: SensorStream, sample: DeviceSample, arrival_ns: int,
              source: str) -> list[StampedSample]:
        """Hold a sample from a source ``stream`` is not bound to; bind that source if it may take the
        id now (its chain confirmed; the bound source, if any, silent for ``stale_after_s``)."""
        pending = self._candidates[stream.sensor_id]
        candidate = pending.get(source)
        if candidate is None:
            if len(pending) >= MAX_CANDIDATES:  # make room by a source that sent no 2 agreeing samples
                idle = [s for s, c in pending.items() if c.root is None and c.chains.longest <= 1]
                if not idle:
                    self._drop(stream, source, 1)
                    return []
                oldest = min(idle, key=lambda s: pending[s].until_ns)
                self._drop(stream, oldest, len(pending.pop(oldest).held))
            candidate = pending[source] = _Candidate()
        candidate.heard(arrival_ns, self.frames)
        candidate.held.append((sample, arrival_ns, self.frames))
        if len(candidate.held) > HOLD_SAMPLES:
            candidate.held.popleft()
            self._drop(stream, source, 1)
        if candidate.root is None:
            chain, _ = candidate.chains.add(sample, arrival_ns, self.frames)
            if chain is None:
                return []
            candidate.root, candidate.period_us = chain[0].sample, chain[-1].period_us
            candidate.chains.clear()
        silent_ns = None if stream.last_arrival_ns is None else arrival_ns - stream.last_arrival_ns
        if stream.source is not None and silent_ns is not None and silent_ns < self._stale_ns:
            return []
        return self._bind(stream, source, silent_ns)

    def _bind(self, stream: SensorStream, source: str, silent_ns: int | None) -> list[StampedSample]:
        """Bind ``stream``'s id to ``source``: its held samples go to the stream in sequence order about
        its confirmed chain (samples far from it after, as they came); the other sources' are dropped."""
        pending = self._candidates[stream.sensor_id]
        candidate = pending.pop(source)
        if stream.source is None:
            self.notices.say("info", f"imu_driver: {stream.name} is heard from {source} ({CONFIRM_SAMPLES}+ "
                             f"agreeing samples in {CONFIRM_FRAMES}+ frames); samples claiming its id from "
                             "elsewhere are dropped while it sends")
        else:
            self.rebinds[stream.sensor_id] += 1
            silent = "" if silent_ns is None else f" for {silent_ns * 1e-9:.1f} s"
            self.notices.say("warn", f"imu_driver: sensor {stream.sensor_id} now sends from {source}, "
                             f"{stream.source} silent{silent}: {stream.segment} is bound to the new source "
                             "(a sensor that picks a new source port when it boots does this)")
            stream.lost += stream.foreign.pop(source, 0)  # its samples dropped before: the sensor's, lost
        stream.source = source
        self._drop_all(stream, pending)
        root = candidate.root.sequence
        near = sorted((h for h in candidate.held if abs(seq_diff(h[0].sequence, root)) <= HOLD_SAMPLES),
                      key=lambda h: seq_diff(h[0].sequence, root))
        far = [h for h in candidate.held if abs(seq_diff(h[0].sequence, root)) > HOLD_SAMPLES]
        out: list[StampedSample] = []
        for sample, arrival, frame in near + far:
            out.extend(stream.push(sample, arrival, frame))
        return out

    def _drop_all(self, stream: SensorStream, pending: dict[str, _Candidate]) -> None:
        for source, candidate in pending.items():
            self._drop(stream, source, len(candidate.held))
        pending.clear()

    def _drop(self, stream: SensorStream, source: str, n: int) -> None:
        """``n`` held samples from ``source`` dropped: foreign if the id is bound to another source,
        else unconfirmed (``rejected``)."""
        if n <= 0:
            return
        if stream.source is not None:
            self._foreign(stream, source, n)
            return
        if stream.rejected == 0:
            self.notices.say("warn", f"imu_driver: {n} sample(s) claiming sensor {stream.sensor_id} from "
                             f"{source} were dropped: no {CONFIRM_SAMPLES} of them agreed in sequence and "
                             f"device time over {CONFIRM_FRAMES} frames arriving in real time; further ones "
                             "are counted on /diagnostics ('rejected')")
        stream.rejected += n

    def _foreign(self, stream: SensorStream, source: str, n: int = 1) -> None:
        """``n`` samples for ``stream``'s id from another source than its own: counted, said once."""
        if not stream.foreign:
            self.notices.say("warn", f"imu_driver: sensor {stream.sensor_id} also sent from {source}: two "
                             f"sources claim one id; {stream.segment} stays bound to {stream.source} while "
                             "it sends, and the other's samples are dropped and counted on /diagnostics. "
                             "Give each sensor its own id")
        if source in stream.foreign or len(stream.foreign) < MAX_FOREIGN_SOURCES:
            stream.foreign[source] = stream.foreign.get(source, 0) + n
        else:
            stream.foreign[OTHER_SOURCES] = stream.foreign.get(OTHER_SOURCES, 0) + n

    def expire(self, now_ns: int) -> list[StampedSample]:
        """Samples whose wait for missing ones has ended (call every few ms). A source not bound whose
        samples waited as long as suspects do (:mod:`~gait_biofeedback.core.driver.chain`) is
        forgotten, its held samples dropped."""
        out: list[StampedSample] = []
        for sid, stream in self.sensors.items():
            out.extend(stream.expire(now_ns))
            pending = self._candidates[sid]
            for candidate in pending.values():
                candidate.chains.expire(now_ns)
            for source in [s for s, c in pending.items() if not c.chains and now_ns > c.until_ns]:
                self._drop(stream, source, len(pending.pop(source).held))
        return out

    def reports(self, now_ns: int) -> list[SensorReport]:
        """One report per mapped sensor, one per unmapped sensor id that sent, and one for the link."""
        stale_ns = self.params.stale_after_s * 1e9
        out = []
        for s in self.sensors.values():
            pending = self._candidates[s.sensor_id]
            values: dict[str, object] = {
                "sensor_id": s.sensor_id, "received": s.received, "published": s.published,
                "lost": s.lost, "late": s.late, "duplicates": s.duplicates, "reboots": s.reboots,
                "clock_resets": s.clock_resets, "stamps_adjusted": s.stamps_adjusted,
                "rejected": s.rejected, "source": s.source or "",
                "foreign_samples": sum(s.foreign.values()), "rate_hz": s.rate_hz(),
                "held": sum(len(c.held) for c in pending.values()), "rebinds": self.rebinds[s.sensor_id]}
            if s.last_arrival_ns is None and pending:
                level, text = 1, (f"sensor {s.sensor_id} heard from {', '.join(pending)}, not confirmed "
                                  f"yet: its samples are held until {CONFIRM_SAMPLES} agree in sequence and "
                                  f"device time over {CONFIRM_FRAMES} frames arriving in real time")
            elif s.last_arrival_ns is None:
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
                        text += f", {s.rejected} unconfirmed sample(s) rejected"
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
            f"({sum(s.foreign.values())} samples dropped; bound to {s.source})")

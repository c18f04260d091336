"""x-io NGIMU sensors over OSC/UDP (decoded with PyPI ``python-osc``), several at once.

Each NGIMU sends OSC bundles to this computer's ``port`` (its "send port" setting, 8000 by default)
over Wi-Fi (NGIMU User Manual v1.6, sections "Communication protocol" and "Sensors message"): every
message inside a bundle whose OSC time tag (NTP format: seconds since 1900 and a 2⁻³² s fraction) is
the time of the measurement on the device's clock. ``/sensors`` carries gyroscope x, y, z (°/s),
accelerometer x, y, z (g), magnetometer x, y, z (µT) and barometer (hPa); converted to SI here
(rad/s, m/s², T; the barometer is not used; a magnetometer reading exactly 0 on all three axes is
taken as none). Other messages (quaternion, battery, ...) are ignored;
a datagram that is not OSC, a ``/sensors`` message outside a bundle (no time tag) or with other
arguments is counted (:attr:`NgimuLink.bad_frames`) and named once, never raised.

A device is named by its address as the packets show it (``IP`` or ``IP:PORT``; ``devices``
parameter). The driver core binds each sensor id to one ``IP:PORT`` source: a second sender claiming
the same device is refused, counted and named on ``/diagnostics``. A sender that is not mapped is
counted and named once with what to do (:meth:`NgimuLink.reports`). The NGIMU sends no sample
counter: sequence numbers come from the time tags
(:class:`~gait_biofeedback.io.vendors.timebase.SequenceFromTime`).
"""

from __future__ import annotations

import math

from gait_biofeedback.core.driver.protocol import DeviceSample
from gait_biofeedback.core.notices import Notices
from gait_biofeedback.io.sensor_links import UdpLink
from gait_biofeedback.io.vendors.timebase import SequenceFromTime

STANDARD_GRAVITY = 9.80665
NTP_TO_UNIX_S = 2_208_988_800
"""s from the NTP epoch (1900) to the Unix epoch (1970)."""
SENSORS_ADDRESS = "/sensors"
MAX_NAMED_SENDERS = 32
"""Unmapped senders counted by name; further ones together."""


class OscError(ValueError):
    """A datagram or message that is not what an NGIMU sends (the message says what)."""


def sensors_sample(sensor_id: int, sequence: int, device_us: int, args: list) -> DeviceSample:
    """The arguments of an NGIMU ``/sensors`` message → one sample in SI units."""
    if len(args) < 9 or not all(isinstance(a, float) and math.isfinite(a) for a in args[:9]):
        raise OscError(f"{SENSORS_ADDRESS} needs 9 finite floats (gyroscope °/s, accelerometer g, "
                       f"magnetometer µT, then barometer hPa), got {args[:10]!r}")
    gyr = tuple(math.radians(v) for v in args[0:3])
    acc = tuple(v * STANDARD_GRAVITY for v in args[3:6])
    # all three exactly 0: no reading (a magnetometer off or failed; the fake device without one)
    mag = tuple(v * 1e-6 for v in args[6:9]) if any(args[6:9]) else None
    return DeviceSample(sensor_id, sequence, device_us, acc, gyr, mag)


def sensors_messages(datagram: bytes) -> list[tuple[int, list]]:
    """One datagram → ``(device time µs since 1900, /sensors arguments)`` of each ``/sensors`` message
    in it; OscError if the datagram is not OSC or a ``/sensors`` message has no time tag."""
    from pythonosc.osc_bundle import OscBundle
    from pythonosc.osc_message import OscMessage

    try:
        if OscBundle.dgram_is_bundle(datagram):
            _check_sizes(datagram)
            return _bundle_sensors(OscBundle(datagram))
        if OscMessage.dgram_is_message(datagram):
            if OscMessage(datagram).address == SENSORS_ADDRESS:
                raise OscError(f"a {SENSORS_ADDRESS} message outside a bundle has no time tag")
            return []
    except OscError:
        raise
    except Exception as err:  # python-osc's ParseError, and what a hostile datagram makes it raise
        raise OscError(f"not an OSC packet ({err})") from err
    raise OscError("not an OSC packet (neither '#bundle' nor an address)")


def _check_sizes(datagram: bytes) -> None:
    """A bundle's elements (OSC 1.0: a 32-bit size, then that many bytes) fill it exactly: python-osc
    takes a message cut short as one with fewer arguments."""
    offset = 16  # '#bundle\0' and the time tag
    while offset + 4 <= len(datagram):
        offset += 4 + int.from_bytes(datagram[offset:offset + 4], "big")  # unsigned: always forward
    if offset != len(datagram):
        raise OscError(f"a bundle cut short or padded: its elements say {offset} bytes, it has "
                       f"{len(datagram)}")


def _bundle_sensors(bundle) -> list[tuple[int, list]]:
    from pythonosc.osc_message import OscMessage

    out = []
    for content in bundle:
        if isinstance(content, OscMessage):
            if content.address == SENSORS_ADDRESS:
                if bundle.timestamp == 0:  # python-osc's IMMEDIATELY: the time tag 1
                    raise OscError(f"a {SENSORS_ADDRESS} bundle's time tag is 'immediately', not a time")
                out.append((round((bundle.timestamp + NTP_TO_UNIX_S) * 1e6), content.params))
        else:
            out.extend(_bundle_sensors(content))
    return out


class NgimuLink:
    """NGIMUs sending to ``address:port`` → samples (module docstring); ``devices`` maps each
    device's ``IP`` or ``IP:PORT`` to its sensor id. ``source`` of a sample is its sender's
    ``IP:PORT``."""

    def __init__(self, address: str, port: int, devices: dict[str, int]) -> None:
        if not devices:
            raise OSError("imu_driver: backend 'ngimu' has no devices: give imu_driver's 'devices' as "
                          "'IP=SEGMENT' or 'IP:PORT=SEGMENT', ... (docs/connecting_sensors.md)")
        try:
            import pythonosc  # noqa: F401
        except ImportError as err:
            raise OSError("imu_driver: backend 'ngimu' needs python-osc: pip install python-osc") from err
        self.udp = UdpLink(address, port)
        self.port = self.udp.port
        self.devices = dict(devices)
        self.description = f"NGIMU over OSC on udp {address}:{self.port} ({len(devices)} devices)"
        self.notices = Notices()
        self.bad_frames = 0
        self.unmapped: dict[str, int] = {}
        self._numbering: dict[str, SequenceFromTime] = {}

    @property
    def arrival_clock(self) -> str | None:
        return self.udp.arrival_clock

    def receive(self, timeout_s: float) -> list[tuple[list[DeviceSample], int, str]]:
        out: list[tuple[list[DeviceSample], int, str]] = []
        for datagram, arrival, source in self.udp.receive(timeout_s):
            sid = self.devices.get(source, self.devices.get(source.rpartition(":")[0]))
            try:
                messages = sensors_messages(datagram)
                if sid is None:
                    if messages:
                        self._unmapped(source)
                    continue
                numbering = self._numbering.setdefault(source, SequenceFromTime())
                for device_us, args in messages:
                    sensors_sample(sid, 0, device_us, args)  # refuse bad arguments before numbering
                    for sample in numbering.push(device_us, (device_us, args, arrival),
                                                 lambda seq, item, sid=sid: (
                                                     sensors_sample(sid, seq, item[0], item[1]), item[2])):
                        out.append(([sample[0]], sample[1], source))
            except OscError as err:
                self.bad_frames += 1
                if self.bad_frames == 1:
                    self.notices.say("warn", f"imu_driver: a datagram from {source} was dropped ({err}); "
                                     "further ones are counted on /diagnostics")
        return out

    def _unmapped(self, source: str) -> None:
        key = source if source in self.unmapped or len(self.unmapped) < MAX_NAMED_SENDERS else "other senders"
        if key not in self.unmapped:
            self.notices.say("warn", f"imu_driver: an NGIMU at {source} sends but is not mapped: add "
                             f"'{source.rpartition(':')[0]}=SEGMENT' to imu_driver's 'devices'")
        self.unmapped[key] = self.unmapped.get(key, 0) + 1

    def reports(self) -> list[tuple[str, int, str, dict[str, object]]]:
        """``/diagnostics`` statuses of the link's own: one per unmapped sender (name, level,
        message, values)."""
        return [(f"imu_driver: NGIMU {source}", 1,
                 f"NGIMU at {source} sends but is not mapped to a segment: add "
                 f"'{source.rpartition(':')[0]}=SEGMENT' to imu_driver's 'devices' (config/session.yaml)",
                 {"source": source, "datagrams": n}) for source, n in sorted(self.unmapped.items())]

    def close(self) -> None:
        self.udp.close()

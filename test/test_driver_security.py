"""imu_driver against forged, replayed, foreign and unsigned frames: a sensor id is bound to the first
source that sends a confirmed chain and moves only once that source is silent; restarts need
confirming samples that arrived in real time; reserved fields are checked; frames can be signed (GBI2)."""

from __future__ import annotations

import hashlib
import hmac
import re
import struct
import zlib

import numpy as np
import pytest
from conftest import through_line_noise

from gait_biofeedback.core.driver.protocol import (
    DeviceSample,
    FrameError,
    SignatureError,
    decode_frame,
    encode_frame,
    frame_size,
    load_frame_key,
)
from gait_biofeedback.core.driver.stream import DriverCore, DriverParams
from gait_biofeedback.core.params import ParameterError

T0 = 1_800_000_000 * 10**9  # host ns
SENSOR = "10.0.0.5:4000"
FORGER = "10.0.0.7:4000"
KEY = b"0123456789abcdef0123456789abcdef"
FORGED_MARK = -1.0
TWO_SOURCES = "also sent from 10.0.0.7:4000: two sources claim one id"


def genuine(seq: int, t_us: int, sid: int = 2) -> DeviceSample:
    """A sample whose acc x carries its sequence number (exact in float32 below 2**24)."""
    return DeviceSample(sid, seq, t_us, (float(seq % 2**24), 0.0, 9.75), (0.0, 0.0, 0.0))


def forged(seq: int, t_us: int, sid: int = 2) -> DeviceSample:
    return DeviceSample(sid, seq, t_us, (FORGED_MARK, 0.0, 0.0), (0.0, 0.0, 0.0))


def link_events(n: int = 300, rate: float = 100.0, seq0: int = 5000, device0_us: int = 42_000_000,
                seed: int = 0, t0_s: float = 0.0, sid: int = 2):
    """``n`` genuine single-sample frames (frame bytes, arrival ns, source, true ns): sample k taken at
    host T0 + t0_s + k / rate, arriving 2 ms + uniform [0, 5 ms] later (never reordered at 100 Hz)."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        true_ns = T0 + round((t0_s + k / rate) * 1e9)
        arrival = true_ns + 2_000_000 + int(rng.integers(0, 5_000_000))
        frame = encode_frame([genuine(seq0 + k, device0_us + round(k * 1e6 / rate), sid)])
        out.append((frame, arrival, SENSOR, true_ns))
    return out


def run(events, core: DriverCore | None = None, sensors=("2:left_shank",)):
    """Feed ``events`` (frame, arrival, source[, ...]) in arrival order, expiring after each: the core
    and the stamp of each published sample by its acc x (the genuine sequence, or FORGED_MARK)."""
    core = core or DriverCore(DriverParams(sensors=sensors))
    stamps: dict[float, int] = {}
    published = []
    for frame, arrival, source, *_ in sorted(events, key=lambda e: e[1]):
        got = core.feed(frame, arrival, source) + core.expire(arrival)
        for s in got:
            stamps[s.acc[0]] = s.stamp_ns
            published.append(s)
    got = core.expire(sorted(events, key=lambda e: e[1])[-1][1] + 10**10)
    published += got
    stamps.update({s.acc[0]: s.stamp_ns for s in got})
    return core, stamps, published


def deviation_ms(clean: dict[float, int], other: dict[float, int]) -> float:
    assert set(other) == set(clean), "the same genuine samples, no more and no fewer"
    return max(abs(other[k] - clean[k]) for k in clean) * 1e-6


def test_the_clean_run_is_stamped_at_the_true_times_plus_the_least_latency():
    events = link_events()
    _, stamps, _ = run(events)
    error_ms = np.array([(stamps[float(5000 + k)] - e[3]) * 1e-6 for k, e in enumerate(events)])
    # the lower line of 2 + U[0, 5] ms delays: never below 2 ms, never above the first delay
    assert len(stamps) == 300 and error_ms.min() >= 1.9 and error_ms.max() <= 7.1


def test_a_forged_frame_from_another_source_records_nothing_and_moves_no_stamp():
    events = link_events()
    _, clean, _ = run(events)
    attack = [*events, (encode_frame([forged(123, 1)]), events[100][1] + 1_000_000, FORGER)]
    core, stamps, published = run(attack)
    assert FORGED_MARK not in stamps and len(published) == 300
    assert deviation_ms(clean, stamps) <= 2.0
    s = core.sensors[2]
    assert (s.source, s.foreign, s.reboots, s.lost, s.rejected) == (SENSOR, {FORGER: 1}, 0, 0, 0)
    warnings = [n.text for n in core.notices.pop() if n.level == "warn"]
    assert len(warnings) == 1 and f"sensor 2 {TWO_SOURCES}" in warnings[0]
    report = {r.name: r for r in core.reports(events[-1][1])}["imu_driver: left_shank"]
    assert report.level == 1 and f"sensor 2 {TWO_SOURCES}" in report.message
    assert report.values["foreign_samples"] == 1 and report.values["source"] == SENSOR


@pytest.mark.parametrize("what, make", [
    ("a restart far behind", lambda k: [forged(123, 1)]),
    ("a new sequence far ahead", lambda k: [forged(5000 + k + 10**6, 1)]),
    ("an outage far ahead, device time fitting",
     lambda k: [forged(5000 + k + 5000, 42_000_000 + (k + 5000) * 10_000)]),
    ("a device clock jump 3 samples ahead", lambda k: [forged(5000 + k + 3, 1)]),
    ("five agreeing samples in one frame", lambda k: [forged(7 + i, 1 + 10_000 * i) for i in range(5)]),
])
def test_a_forged_frame_from_the_sensors_own_address_restarts_nothing_and_moves_no_stamp(what, make):
    events = link_events()
    _, clean, _ = run(events)
    k = 100  # after genuine sample 100 (sequence 5100)
    frame = encode_frame(make(k + 1))
    core = DriverCore(DriverParams(sensors=("2:left_shank",)))
    observed = []
    observe = core.sensors[2].clock.observe
    core.sensors[2].clock.observe = lambda d, a: (observed.append(d), observe(d, a))[1]
    attack = [*events, (frame, events[k][1] + 1_000_000, SENSOR)]
    core, stamps, published = run(attack, core)
    s = core.sensors[2]
    assert FORGED_MARK not in stamps and len(published) == 300, what
    assert deviation_ms(clean, stamps) <= 2.0, what
    assert (s.reboots, s.clock_resets, s.lost, s.duplicates) == (0, 0, 0, 0), what
    assert s.rejected == len(decode_frame(frame)), what  # set aside, then dropped when the sensor went on
    assert sorted(observed) == [42_000_000 + 10_000 * i for i in range(300)], "the clock saw only genuine"


def test_a_single_sample_off_its_sequence_in_time_does_not_reset_the_clock():
    events = link_events()
    _, clean, _ = run(events)
    # sample 150 comes with its device time 100 s off (a glitch): dropped, counted; later ones unmoved
    glitch = encode_frame([genuine(5150, 42_000_000 + 1_500_000 + 100_000_000)])
    events2 = [*events[:150], (glitch, events[150][1], SENSOR), *events[151:]]
    core, stamps, _ = run(events2)
    s = core.sensors[2]
    assert (s.clock_resets, s.rejected, s.lost, s.published) == (0, 1, 1, 299)
    del clean[5150.0]
    assert deviation_ms(clean, stamps) <= 2.0


def test_a_second_sender_on_one_id_for_3_s_is_dropped_counted_and_said_once():
    sensors = ("4:right_thigh",)
    events = link_events(600, sid=4)
    _, clean, _ = run(events, sensors=sensors)
    rng = np.random.default_rng(9)
    other = [(encode_frame([forged(k, 10_000 * k, sid=4)]),  # its own sequence and clock from 0
              T0 + 1_500_000_000 + k * 10_000_000 + int(rng.integers(0, 3_000_000)), FORGER)
             for k in range(300)]
    core, stamps, published = run(events + other, sensors=sensors)
    s = core.sensors[4]
    assert FORGED_MARK not in stamps and len(published) == 600
    assert (s.lost, s.reboots, s.rejected, s.foreign) == (0, 0, 0, {FORGER: 300})
    assert deviation_ms(clean, stamps) <= 2.0
    warnings = [n.text for n in core.notices.pop() if n.level == "warn"]
    assert len(warnings) == 1 and f"sensor 4 {TWO_SOURCES}" in warnings[0]
    report = {r.name: r for r in core.reports(events[-1][1])}["imu_driver: right_thigh"]
    assert report.level == 1 and report.values["foreign_samples"] == 300 and report.values["lost"] == 0
    assert "(300 samples dropped; bound to 10.0.0.5:4000" in report.message


def _rebooting(with_forged: bool):
    """300 samples, 0.3 s of silence, then the sensor restarts: sequence from 0, device clock from
    1.2 s (its boot), 200 samples; optionally a forged frame (sequence 123, 1 µs) from its own address
    between the 2nd and 3rd sample after the restart."""
    before = link_events(300)
    after = link_events(200, seq0=0, device0_us=1_200_000, seed=1, t0_s=3.3)
    events = before + after
    if with_forged:
        events.append((encode_frame([forged(123, 1)]), (after[1][1] + after[2][1]) // 2, SENSOR))
    return events, after


def test_a_genuine_reboot_is_taken_once_confirmed_and_stamped_right():
    events, after = _rebooting(False)
    core = DriverCore(DriverParams(sensors=("2:left_shank",)))
    counts = []
    for frame, arrival, source, *_ in sorted(events, key=lambda e: e[1]):
        counts.append(len(core.feed(frame, arrival, source)))
    s = core.sensors[2]
    # nothing goes out for the first 4 restarted samples, the 5th confirms: all 5 at once
    assert counts[300:306] == [0, 0, 0, 0, 5, 1]
    assert (s.reboots, s.lost, s.rejected, s.published) == (1, 0, 0, 500)
    _, stamps, _ = run(events)
    error_ms = np.array([(stamps[float(k)] - e[3]) * 1e-6 for k, e in enumerate(after)])
    assert error_ms.min() >= 1.9 and error_ms.max() <= 7.1  # the new clock mapped afresh, right
    ordered = [stamps[float(5000 + k)] for k in range(300)] + [stamps[float(k)] for k in range(200)]
    assert (np.diff(ordered) > 0).all()
    texts = [n.text for n in core.notices.pop()]
    assert any("left_shank (sensor 2) restarted (sequence 5299 → 0" in t and "confirmed by 5" in t
               for t in texts)


def test_a_forged_frame_inside_a_reboots_confirmation_is_rejected_and_moves_no_stamp():
    clean_events, _ = _rebooting(False)
    _, clean, _ = run(clean_events)
    events, _ = _rebooting(True)
    core, stamps, _ = run(events)
    s = core.sensors[2]
    assert FORGED_MARK not in stamps and deviation_ms(clean, stamps) <= 2.0
    assert (s.reboots, s.rejected, s.lost) == (1, 1, 0)


def test_a_simulated_sensor_looping_its_scenario_is_a_reboot_each_pass(tmp_path):
    from conftest import synthetic_imu

    from gait_biofeedback.sim.sensor_link import FrameSchedule, LinkModel

    schedule = FrameSchedule(synthetic_imu(["pelvis", "chest"], duration=2.0), {"pelvis": 0, "chest": 7},
                             LinkModel())
    core = DriverCore(DriverParams())
    published = 0
    for lap in range(3):  # as PacedLink with sim_loop: the same schedule again, 2 s later each time
        for i, send in enumerate(schedule.send_ns.tolist()):
            arrival = T0 + lap * 2_000_000_000 + send
            published += len(core.feed(schedule.frame(i), arrival, "simulator")) + len(core.expire(arrival))
    for sid in (0, 7):
        s = core.sensors[sid]
        assert (s.reboots, s.lost, s.rejected, s.published) == (2, 0, 0, 600)
    assert published == 1200


def _with_crc(body: bytes) -> bytes:
    return body + struct.pack("<I", zlib.crc32(body))


@pytest.mark.parametrize("offset, name", [(6, "the header's reserved field is 0xffff"),
                                          (10, "sample 1's reserved field is 0xffff")])
def test_a_frame_with_a_reserved_field_not_0_is_refused_as_corrupt(offset, name):
    frame = bytearray(encode_frame([genuine(1, 5)]))
    frame[offset:offset + 2] = b"\xff\xff"
    bad = _with_crc(bytes(frame[:-4]))  # a valid CRC: only the reserved field is wrong
    with pytest.raises(FrameError, match=name):
        decode_frame(bad)
    core = DriverCore(DriverParams(sensors=("2:left_shank",)))
    assert core.feed(bad, T0, SENSOR) == [] and core.bad_frames == 1 and core.sensors[2].received == 0


def test_a_signed_frame_round_trips_and_carries_the_documented_tag():
    samples = [genuine(7, 10_000), genuine(8, 20_000, sid=3)]
    data = encode_frame(samples, KEY)
    assert len(data) == 8 + 2 * 40 + 16 + 4 == frame_size(2, False, signed=True)
    assert data[:4] == b"GBI2"
    # the tag, by hand: HMAC-SHA256 over header and samples, first 16 bytes; then the CRC of all before it
    assert data[88:104] == hmac.new(KEY, data[:88], hashlib.sha256).digest()[:16]
    assert struct.unpack("<I", data[104:]) == (zlib.crc32(data[:104]),)
    out = decode_frame(data, KEY)
    assert [(s.sensor_id, s.sequence, s.device_time_us, s.acc) for s in out] == [
        (2, 7, 10_000, (7.0, 0.0, 9.75)), (3, 8, 20_000, (8.0, 0.0, 9.75))]


def test_wrong_missing_or_tampered_signatures_are_refused():
    signed = encode_frame([genuine(1, 5)], KEY)
    with pytest.raises(SignatureError, match="not signed with the session key") as err:
        decode_frame(signed, b"another key, 16+ bytes long")
    assert err.value.reason == "wrong key"
    with pytest.raises(SignatureError) as err:
        decode_frame(encode_frame([genuine(1, 5)]), KEY)
    assert err.value.reason == "unsigned"
    with pytest.raises(SignatureError, match="no session key is set") as err:
        decode_frame(signed, None)
    assert err.value.reason == "no key"
    tampered = bytearray(signed)
    tampered[20] ^= 0x01  # a byte of the device time changed; the CRC made right again
    tampered = _with_crc(bytes(tampered[:-4]))
    with pytest.raises(SignatureError) as err:
        decode_frame(tampered, KEY)
    assert err.value.reason == "wrong key"
    damaged = signed[:20] + bytes([signed[20] ^ 1]) + signed[21:]  # damaged on the way: the CRC says so
    with pytest.raises(FrameError, match="CRC mismatch"):
        decode_frame(damaged, KEY)


def _key_file(tmp_path, content=KEY + b"\n", mode=0o600):
    path = tmp_path / "frame.key"
    path.write_bytes(content)
    path.chmod(mode)
    return str(path)


def test_a_driver_with_a_key_takes_only_frames_signed_with_it_and_says_so(tmp_path):
    core = DriverCore(DriverParams(sensors=("2:left_shank",), frame_key_file=_key_file(tmp_path)))
    assert core.signed
    got = [len(core.feed(encode_frame([genuine(k, 10_000 * k)], KEY), T0 + k * 10**7, SENSOR))
           for k in range(5)]
    assert got == [0, 0, 0, 0, 5]  # held until 5 agreeing samples confirm their source, then all out
    assert core.feed(encode_frame([forged(5, 50_000)]), T0 + 5 * 10**7, FORGER) == []
    for k in range(6, 9):
        assert core.feed(encode_frame([forged(k, 10_000 * k)], b"a guessed key 0123456"), T0 + k * 10**7,
                         SENSOR) == []
    # the refused frames were never samples: the genuine sequence goes on with no gap
    assert len(core.feed(encode_frame([genuine(5, 50_000)], KEY), T0 + 9 * 10**7, SENSOR)) == 1
    assert (core.sensors[2].lost, core.sensors[2].received) == (0, 6)
    assert core.refused == {"unsigned": 1, "wrong key": 3, "no key": 0}
    assert core.sensors[2].foreign == {}  # a refused frame binds nothing and counts as no sample
    link = {r.name: r for r in core.reports(T0 + 10 * 10**7)}["imu_driver: link"]
    assert "4 frames refused: not signed with the session key" in link.message
    assert link.values["unsigned_frames"] == 1 and link.values["wrongly_signed_frames"] == 3
    texts = [n.text for n in core.notices.pop()]
    assert sum("refused" in t for t in texts) == 2  # once per reason, not once per frame
    everything = " ".join(texts + [r.message + str(r.values) for r in core.reports(T0)])
    assert KEY.decode() not in everything  # the key is never said


def test_signed_frames_without_a_key_are_refused_with_one_clear_notice():
    core = DriverCore(DriverParams(sensors=("2:left_shank",)))
    for k in range(3):
        assert core.feed(encode_frame([genuine(k, 10_000 * k)], KEY), T0 + k * 10**7, SENSOR) == []
    texts = [n.text for n in core.notices.pop()]
    assert texts == ["imu_driver: signed frames came but no session key is set: set imu_driver's "
                     "'frame_key_file' to the sensors' key file"]
    link = {r.name: r for r in core.reports(T0)}["imu_driver: link"]
    assert "3 signed frames refused: no session key is set" in link.message


def test_the_key_file_must_be_private_and_long_enough(tmp_path):
    assert load_frame_key(_key_file(tmp_path)) == KEY  # the final newline is not part of the key
    for mode in (0o640, 0o604):
        with pytest.raises(ValueError, match=r"read by other users \(mode 06[04][04]\): .*chmod 600") as err:
            load_frame_key(_key_file(tmp_path, mode=mode))
        assert KEY.decode() not in str(err.value)
    with pytest.raises(ValueError, match="holds 5 bytes; a session key has at least 16"):
        load_frame_key(_key_file(tmp_path, b"short\n"))
    with pytest.raises(ParameterError, match="'frame_key_file': cannot read frame key file"):
        DriverCore(DriverParams(frame_key_file=str(tmp_path / "missing.key")))


def test_the_serial_reader_finds_signed_frames_in_noise():
    rng = np.random.default_rng(5)
    frames = [encode_frame([genuine(i, 1000 * i)], KEY if i % 3 else None) for i in range(120)]
    damaged = {10, 55}
    # noise, with false magic starts
    got, _ = through_line_noise(frames, damaged, rng, max_noise=8, cuts=90, before=b"GBI")
    assert [f[:4] for f in got] == [b"GBI2" if i % 3 else b"GBI1" for i in range(120) if i not in damaged]
    seqs = [decode_frame(f, KEY if f[:4] == b"GBI2" else None)[0].sequence for f in got]
    assert seqs == [i for i in range(120) if i not in damaged]


def test_stream_sim_signs_and_run_passes_the_key_file_to_the_driver(tmp_path, monkeypatch):
    from conftest import synthetic_imu

    from gait_biofeedback import cli, graph
    from gait_biofeedback.io.bag import write_imu_bag
    from gait_biofeedback.sim import sensor_link

    key_file = _key_file(tmp_path)
    given = {}
    monkeypatch.setattr(graph, "run_live", lambda nodes, record, params, **kw: given.update(params) or 0)
    assert cli.main(["run", "--driver", "udp:5601", "--frame-key-file", key_file, "--nodes", ""]) == 0
    assert given["imu_driver"] == {"backend": "udp", "port": 5601, "frame_key_file": key_file}
    assert cli.main(["run", "--frame-key-file", key_file]) == 2  # a key without a driver is a mistake
    bag = write_imu_bag(tmp_path / "in", synthetic_imu(["pelvis"], duration=0.2))
    sent = {}

    def fake_send(schedule, host, port, **kw):
        sent["frame"] = schedule.frame(0)
        return sensor_link.SendReport(0, 20, 0, 20, 0.0)

    monkeypatch.setattr(sensor_link, "send_udp", fake_send)
    assert cli.main(["stream-sim", str(bag), "--to", "udp:127.0.0.1:5601", "--frame-key-file", key_file]) == 0
    assert sent["frame"][:4] == b"GBI2" and decode_frame(sent["frame"], KEY)[0].sensor_id == 0


def test_a_consistent_forged_stream_between_the_sensors_own_samples_restarts_nothing():
    events = link_events()
    _, clean, _ = run(events)
    # from the sensor's own address, 10 frames that agree with each other (a restart from sequence 0 at
    # 100 Hz), each sent 1 ms after a genuine one: the genuine samples in between void the chain
    attack = [*events, *((encode_frame([forged(i, 1 + 10_000 * i)]), events[100 + i][1] + 1_000_000, SENSOR)
                         for i in range(10))]
    core, stamps, published = run(attack)
    s = core.sensors[2]
    assert FORGED_MARK not in stamps and len(published) == 300 and deviation_ms(clean, stamps) <= 2.0
    assert (s.reboots, s.rejected, s.lost) == (0, 10, 0)


def test_a_genuine_long_outage_is_confirmed_as_loss_not_a_reboot():
    # 3 s of samples, 15 s out of range (1500 samples never arrive), then the same clock and sequence on
    events = link_events(300) + link_events(100, seq0=6800, device0_us=42_000_000 + 18_000_000, seed=2,
                                            t0_s=18.0)
    core, stamps, published = run(events)
    s = core.sensors[2]
    assert (s.reboots, s.clock_resets, s.rejected, s.lost, len(published)) == (0, 0, 0, 1500, 400)
    error_ms = np.array([(stamps[float(6800 + k)] - e[3]) * 1e-6 for k, e in enumerate(events[300:])])
    assert error_ms.min() >= 1.9 and error_ms.max() <= 7.1  # the clock line went on, unreset


NEW_PORT = "10.0.0.5:4001"


def _signed(events, key=KEY):
    """``events`` with their frames signed."""
    return [(encode_frame(decode_frame(f), key), a, src, *rest) for f, a, src, *rest in events]


@pytest.mark.parametrize("resends", [1, 10])
def test_a_replayed_signed_frame_from_another_address_cannot_take_the_sensors_id(tmp_path, resends):
    # a signed frame of the sensor's, captured (this session or an earlier one with the same key), is sent
    # from another address before the sensor's first frame (once, or 10 times over 1 s): one frame is no
    # chain of samples, so it binds nothing; the sensor's own 500 frames all go out
    core = DriverCore(DriverParams(sensors=("2:left_shank",), frame_key_file=_key_file(tmp_path)))
    events = _signed(link_events(500, t0_s=0.1))
    captured = encode_frame([genuine(4990, 41_900_000)], KEY)
    replays = [(captured, T0 + i * 100_000_000, FORGER) for i in range(resends)]
    core, _, published = run(events + replays, core)
    s = core.sensors[2]
    assert [p.acc[0] for p in published] == [float(5000 + k) for k in range(500)]
    assert (s.source, s.foreign, s.lost, s.reboots) == (SENSOR, {FORGER: resends}, 0, 0)
    warnings = [n.text for n in core.notices.pop() if n.level == "warn"]
    assert len(warnings) == 1 and f"sensor 2 {TWO_SOURCES}" in warnings[0]  # the replayer is named, once


@pytest.mark.parametrize("per_frame", [1, 4])
def test_the_first_samples_wait_for_their_source_to_be_confirmed_and_none_is_lost(per_frame):
    # 100 Hz in frames of `per_frame`; the 2nd frame comes after the 3rd, the 5th never comes
    rng = np.random.default_rng(per_frame)
    frames = []
    for f in range(60):
        ks = range(f * per_frame, (f + 1) * per_frame)
        arrival = T0 + ks[-1] * 10**7 + 2_000_000 + int(rng.integers(0, 5_000_000)) + (
            25_000_000 * per_frame if f == 1 else 0)
        if f != 4:
            frames.append((encode_frame([genuine(5000 + k, 42_000_000 + 10_000 * k) for k in ks]), arrival))
    core = DriverCore(DriverParams(sensors=("2:left_shank",)))
    counts, out = [], []
    for frame, arrival in sorted(frames, key=lambda f: f[1]):
        got = core.feed(frame, arrival, SENSOR) + core.expire(arrival)
        counts.append(len(got))
        out += got
    out += core.expire(frames[-1][1] + 10**10)
    s = core.sensors[2]
    confirming = next(i for i, n in enumerate(counts) if n)
    assert confirming >= 2 and counts[confirming] >= per_frame  # held until confirmed, then out together
    expected = [float(5000 + k) for k in range(60 * per_frame) if not 4 * per_frame <= k < 5 * per_frame]
    assert [o.acc[0] for o in out] == expected  # in sequence order, the reordered frame in its place
    assert (s.lost, s.late, s.duplicates, s.rejected) == (per_frame, 0, 0, 0)
    assert (np.diff([o.stamp_ns for o in out]) > 0).all()


def test_a_sensor_back_from_a_new_source_port_takes_its_id_once_the_old_one_is_silent():
    # sensor 4 sends from port 4000 for 3 s, reboots and sends from port 4001 0.5 s later (lwIP on an ESP32
    # picks a new source port at each boot): sequence from 0, device clock from 0.4 s
    sensors = ("4:right_thigh",)
    new = link_events(300, seq0=0, device0_us=400_000, seed=3, t0_s=3.5, sid=4)
    core, stamps, published = run(link_events(300, sid=4) + [(f, a, NEW_PORT, t) for f, a, _, t in new],
                                  sensors=sensors)
    s = core.sensors[4]
    assert (s.source, core.rebinds[4], s.reboots, s.lost, s.rejected, s.foreign) == (NEW_PORT, 1, 1, 0, 0, {})
    assert len(published) == 600  # the new source's samples held while the old one was not yet silent 1 s
    error_ms = np.array([(stamps[float(k)] - e[3]) * 1e-6 for k, e in enumerate(new)])
    assert error_ms.min() >= 1.9 and error_ms.max() <= 7.1
    warnings = [n.text for n in core.notices.pop() if n.level == "warn"]
    moved = [t for t in warnings if "now sends from" in t]
    assert len(moved) == 1 and re.search(r"sensor 4 now sends from 10\.0\.0\.5:4001, 10\.0\.0\.5:4000 "
                                          r"silent for 1\.\d s", moved[0])
    report = {r.name: r for r in core.reports(new[-1][1])}["imu_driver: right_thigh"]
    assert report.level == 0 and report.values["rebinds"] == 1 and report.values["source"] == NEW_PORT


def test_while_its_source_sends_no_other_source_takes_the_id_even_across_a_short_pause():
    # sensor 4 is out of range for 0.8 s (under stale_after_s, 1 s) while another source streams a sequence
    # of its own, in real time, from 0.9 s to 2.5 s
    sensors = ("4:right_thigh",)
    events = [e for k, e in enumerate(link_events(300, sid=4)) if not 100 <= k < 180]
    other = [(encode_frame([forged(k, 10_000 * k, sid=4)]), T0 + 900_000_000 + k * 10_000_000, FORGER)
             for k in range(160)]
    core, stamps, published = run(events + other, sensors=sensors)
    s = core.sensors[4]
    assert FORGED_MARK not in stamps and len(published) == 220
    assert (s.source, core.rebinds[4], s.reboots, s.lost, s.foreign) == (SENSOR, 0, 0, 80, {FORGER: 160})


def test_held_samples_are_bounded_and_the_rest_counted():
    from gait_biofeedback.core.driver.stream import HOLD_SAMPLES, MAX_CANDIDATES

    # before the sensor's first frame, one source sends 10 full frames (2550 samples) in one burst, never a
    # confirmed chain, and 40 sources send one frame each; then the sensor starts
    burst = [(encode_frame([forged(255 * f + i, 1 + 1000 * (255 * f + i)) for i in range(255)]), T0 + f,
              "10.0.0.9:1") for f in range(10)]
    single = [(encode_frame([forged(7 * p, 1)]), T0 + 1_000_000 * (p + 1), f"10.0.0.8:{p}")
              for p in range(40)]
    events = burst + single + link_events(300, t0_s=0.1)
    core = DriverCore(DriverParams(sensors=("2:left_shank",)))
    most = 0
    published = []
    for frame, arrival, source, *_ in sorted(events, key=lambda e: e[1]):
        published += core.feed(frame, arrival, source) + core.expire(arrival)
        most = max(most, core.reports(arrival)[0].values["held"])
    published += core.expire(events[-1][1] + 10**10)
    s = core.sensors[2]
    # the burst's source capped; 3 other sources at most beside it, the sensor's with its first few samples
    assert HOLD_SAMPLES <= most <= HOLD_SAMPLES + (MAX_CANDIDATES - 1) * 5
    assert FORGED_MARK not in {p.acc[0] for p in published} and len(published) == 300
    assert (s.source, s.lost) == (SENSOR, 0)
    assert s.rejected + sum(s.foreign.values()) == 2550 + 40  # every sample not taken is counted


@pytest.mark.parametrize("frames, per_frame, period_us", [(3, 2, 10_000), (5, 1, 10_000), (3, 2, 250),
                                                          (5, 10, 1000)])
def test_a_burst_of_forged_frames_within_1_ms_from_the_sensors_address_restarts_nothing(frames, per_frame,
                                                                                        period_us):
    # unsigned: a restart from sequence 7, its samples agreeing in sequence and device time (at 100 Hz,
    # 4 kHz or 1 kHz), sent within 1 ms after genuine sample 100: they did not arrive in real time
    events = link_events()
    _, clean, _ = run(events)
    burst = [(encode_frame([forged(7 + f * per_frame + i, 1 + period_us * (f * per_frame + i))
                            for i in range(per_frame)]), events[100][1] + 1_000_000 + f * 1_000_000 // frames,
              SENSOR) for f in range(frames)]
    core, stamps, published = run(events + burst)
    s = core.sensors[2]
    assert FORGED_MARK not in stamps and len(published) == 300 and deviation_ms(clean, stamps) <= 2.0
    assert (s.reboots, s.clock_resets, s.lost, s.rejected) == (0, 0, 0, frames * per_frame)


def test_a_rebooted_sensor_that_first_sends_a_backlog_burst_then_streams_is_confirmed():
    # after the restart the sensor's first 30 samples were buffered: they arrive together (within 0.9 ms)
    # with the 30th; the rest stream in real time
    before = link_events(300)
    after = link_events(200, seq0=0, device0_us=1_200_000, seed=1, t0_s=3.3)
    burst_at = after[29][1]
    after = [(f, burst_at + 30_000 * i if i < 30 else a, src, t) for i, (f, a, src, t) in enumerate(after)]
    core, _, published = run(before + after)
    s = core.sensors[2]
    assert (s.reboots, s.lost, s.rejected, len(published)) == (1, 0, 0, 500)
    assert [p.acc[0] for p in published] == [float(k) for k in [*range(5000, 5300), *range(200)]]
    assert (np.diff([p.stamp_ns for p in published]) > 0).all()


def test_the_key_file_is_checked_as_opened_not_by_its_name(tmp_path, monkeypatch):
    import os
    import stat

    path = _key_file(tmp_path, mode=0o644)
    real_stat = os.stat

    def looks_private(p, *args, **kwargs):  # as if a private file were swapped for this one after a check
        info = real_stat(p, *args, **kwargs)
        return os.stat_result((stat.S_IFREG | 0o600, *info[1:10]))

    monkeypatch.setattr(os, "stat", looks_private)
    with pytest.raises(ValueError, match=r"may be read by other users \(mode 0644\)"):
        load_frame_key(path)
    monkeypatch.undo()
    fifo = tmp_path / "fifo.key"
    os.mkfifo(fifo, 0o600)
    with pytest.raises(ValueError, match="is not a regular file"):
        load_frame_key(fifo)  # refused at once: opening it does not wait for a writer

"""A corrupt byte in a complete recording is never read as data (issue 12, line 8).

Every chunk's CRC and the summary's CRC are checked; a bad chunk is skipped with a warning naming
the time range it took away; ``info`` and ``repair`` report it; ``repair`` keeps every readable
chunk; ``analyze`` goes on without it.
"""

from __future__ import annotations

import shutil
import struct
import warnings

import numpy as np
import pytest
from conftest import synthetic_imu

from gait_biofeedback.cli import main
from gait_biofeedback.io.bag import BagReader, BagRecoveryWarning, repair, write_imu_bag
from gait_biofeedback.io.mcap_file import (
    _DAMAGE_ERRORS,
    OP_MESSAGE,
    McapFile,
    RawMessage,
    _chunk_message_list,
)


def _bag(tmp_path):
    imu = synthetic_imu(["pelvis", "left_foot"], duration=20.0, with_mag=False)
    return write_imu_bag(tmp_path / "good", imu, chunk_size=64 * 1024)


def _read(path) -> tuple[list[tuple[str, bytes, int]], list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", BagRecoveryWarning)
        with BagReader(path) as reader:
            messages = [(t, bytes(d), log) for t, _, d, log in reader.raw_messages()]
    return messages, [str(w.message) for w in caught if issubclass(w.category, BagRecoveryWarning)]


def _flip(folder, position: int) -> None:
    (file,) = folder.glob("*.mcap")
    data = bytearray(file.read_bytes())
    data[position] ^= 0x5A
    file.write_bytes(bytes(data))


def test_no_single_byte_flip_is_read_silently_as_data(tmp_path):
    good = _bag(tmp_path)
    original, said = _read(good)
    assert not said and len(original) == 4000
    known = set(original)
    (file,) = good.glob("*.mcap")
    size = file.stat().st_size
    for k, position in enumerate(np.linspace(40, size - 9, 31).astype(int)):
        copy = tmp_path / f"flip{k}"
        shutil.copytree(good, copy)
        _flip(copy, int(position))
        try:
            messages, said = _read(copy)
        except ValueError:  # refused as a whole (e.g. the header's magic): nothing read wrongly
            continue
        assert set(messages) <= known, f"byte {position}: changed data were read as data"
        if len(messages) < len(original):
            assert said, f"byte {position}: {len(original) - len(messages)} messages lost without a word"


def test_info_repair_and_analyze_name_the_bad_chunk(tmp_path, capsys):
    good = _bag(tmp_path)
    original, _ = _read(good)
    mcap = McapFile.open(next(good.glob("*.mcap")))
    chunks = sorted(mcap.chunks, key=lambda c: c.offset)
    assert len(chunks) >= 4
    middle = chunks[len(chunks) // 2]
    t0 = (middle.start - mcap.start_time) / 1e9
    in_middle = {(m.log_time, m.data) for m in mcap._chunk_messages(middle, None)}
    mcap.close()
    bad = tmp_path / "bad"
    shutil.copytree(good, bad)
    _flip(bad, middle.offset + 200)  # inside its compressed records

    assert main(["info", str(bad)]) == 1
    out = capsys.readouterr().out
    assert f"DAMAGED: {next(bad.glob('*.mcap'))}: chunk at byte {middle.offset - 9} unreadable" in out
    assert f"data from {t0:.2f} s" in out and "gait-biofeedback repair" in out
    kept = [m for m in original if (m[2], m[1]) not in in_middle]
    lost = len(original) - len(kept)
    assert f"{len(kept)} messages" in out.splitlines()[0], "the counts leave out what cannot be read"

    messages, said = _read(bad)
    assert messages == kept and len(said) == 1 and f"{lost} messages" in said[0]

    report = repair(bad)
    (entry,) = report["files"]
    assert entry["status"] == "repaired" and "unreadable" in entry["damage"]
    assert report["message_count"] == len(kept)
    messages, said = _read(bad)
    assert messages == kept and not said, "the repaired file is whole and holds every readable chunk"

    capsys.readouterr()
    shutil.rmtree(bad)
    shutil.copytree(good, bad)
    _flip(bad, middle.offset + 200)
    assert main(["analyze", str(bad), "-o", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "unreadable" in err and f"data from {t0:.2f} s" in err and "skipped" in err


def test_a_cut_recording_with_a_bad_first_chunk_keeps_its_later_chunks(tmp_path):
    """The writer defines each topic only in the chunk of its first message: when that chunk is bad
    in a file without a summary (a crash), its definitions are taken from it (with a warning) so the
    later chunks stay readable, and the counts say what is readable."""
    good = _bag(tmp_path)
    original, _ = _read(good)
    (file,) = good.glob("*.mcap")
    mcap = McapFile.open(file)
    chunks = sorted(mcap.chunks, key=lambda c: c.offset)
    first = chunks[0]
    in_first = {(m.log_time, m.data) for m in mcap._chunk_messages(first, None)}
    summary_at = max(c.offset for c in chunks) + 60_000  # cut inside the data after the last chunk
    mcap.close()
    data = bytearray(file.read_bytes())
    data[first.offset + 300] ^= 0x5A
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(bytes(data[: min(summary_at, len(data) - 100)]))
    messages, said = _read(cut)
    assert messages and set(messages) <= set(original)
    assert not {(m[2], m[1]) for m in messages} & in_first
    assert len(messages) >= len(original) - len(in_first) - 2 * len(original) // len(chunks)
    assert any("topic definition(s) taken from an unreadable chunk" in w for w in said)
    with pytest.warns(BagRecoveryWarning), BagReader(cut) as reader:
        assert reader.message_count == len(messages)
        assert sorted(reader.topics()) == ["/left_foot/imu/data_raw", "/pelvis/imu/data_raw"]


def _record(op: int, body: bytes) -> bytes:
    return struct.pack("<BQ", op, len(body)) + body


def test_a_chunks_message_records_are_read_by_hand_derived_layout():
    """The one-loop chunk parser against records written here by the MCAP layout (opcode, length,
    channel id, sequence, log time, publish time, data): other records are skipped, the channel
    filter holds, a record that overruns the chunk or a message record read that is shorter than its
    head is damage (one of the errors that set a chunk aside, said, instead of ending the read); another
    channel's short record is skipped unread."""
    first = _record(OP_MESSAGE, struct.pack("<HIQQ", 3, 7, 1_000, 1_001) + b"abc")
    other = _record(0x0A, b"x" * 5)  # a record the parser skips
    second = _record(OP_MESSAGE, struct.pack("<HIQQ", 4, 8, 2_000, 2_002) + b"")
    chunk = first + other + second
    assert _chunk_message_list(chunk, None) == [RawMessage(1_000, 3, 1_001, 7, b"abc"),
                                                RawMessage(2_000, 4, 2_002, 8, b"")]
    assert _chunk_message_list(chunk, frozenset({4})) == [RawMessage(2_000, 4, 2_002, 8, b"")]
    with pytest.raises(ValueError, match="overruns the chunk"):
        _chunk_message_list(chunk + struct.pack("<BQ", OP_MESSAGE, 100), None)
    short = _record(OP_MESSAGE, struct.pack("<H", 9) + bytes(5))  # channel 9, then 5 of 20 bytes
    with pytest.raises(ValueError, match="shorter than its head"):
        _chunk_message_list(short + first, None)
    assert issubclass(ValueError, _DAMAGE_ERRORS)
    assert _chunk_message_list(first + short, frozenset({3})) == [RawMessage(1_000, 3, 1_001, 7, b"abc")]


def test_analyze_says_a_cut_recording_once(tmp_path, capsys):
    """A recording cut short (no summary: the recorder died) is said once by ``analyze``, however many
    times the analysis opens it (its rates, the calibration search, the pass itself)."""
    good = _bag(tmp_path)
    (file,) = good.glob("*.mcap")
    cut = tmp_path / "cut"
    cut.mkdir()
    (cut / file.name).write_bytes(file.read_bytes()[: file.stat().st_size // 2])
    assert main(["analyze", str(cut), "-o", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert err.count("damaged or unfinished MCAP file") == 1, err

"""Bounded resources on every input: a hostile YAML file (alias bomb, deep nesting, a huge value or
size), a CSV of millions of rows, a flood of refused dashboard requests each end in one line (or a
bounded log) within bounded memory and time."""

from __future__ import annotations

import contextlib
import http.client
import itertools
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import yaml

from gait_biofeedback.cli import main
from gait_biofeedback.core.params import ParameterError
from gait_biofeedback.core.safe_yaml import MAX_BYTES, YamlRefusedError, dump_yaml, load_yaml, load_yaml_file
from gait_biofeedback.parameters import load_params_file

REPO = Path(__file__).resolve().parents[1]


_LAUNCHER = """
import os, sys
pid = os.fork()
if pid == 0:
    os.execv(sys.executable, [sys.executable, "-m", "gait_biofeedback.cli", *sys.argv[2:]])
_, status, usage = os.wait4(pid, 0)
with open(sys.argv[1], "w") as f:
    f.write(str(usage.ru_maxrss))
sys.exit(os.waitstatus_to_exitcode(status))
"""


def _cli_child(*argv: str, timeout: float = 60.0) -> tuple[int, str, str, float, float]:
    """``gait-biofeedback ARGV`` in a child process: (exit code, stdout, stderr, s, peak RSS MB of that
    child alone, from wait4). A process's peak RSS counts what its parent held when it forked it (the
    pages it inherited, kept across exec): forked from a pytest worker of 600 MB, the CLI would show
    600 MB whatever it did. So a small launcher process forks it and reports its peak."""
    t0 = time.monotonic()
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err, \
            tempfile.NamedTemporaryFile("r") as peak:
        proc = subprocess.Popen([sys.executable, "-c", _LAUNCHER, peak.name, *argv], cwd=REPO, stdout=out,
                                stderr=err, start_new_session=True)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)  # the launcher and the CLI it forked
            proc.wait()
        out.seek(0)
        err.seek(0)
        kb = peak.read().strip()
        return proc.returncode, out.read(), err.read(), time.monotonic() - t0, float(kb or "nan") / 1024


def _alias_bomb(levels: int = 9) -> str:
    """The classic: 9 "lol"s, then each level a list of 9 aliases of the one before (9**9 strings)."""
    names = "abcdefghijklmnop"[:levels]
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    lines += [f"{n}: &{n} [{','.join([f'*{p}'] * 9)}]" for p, n in itertools.pairwise(names)]
    return "\n".join(lines) + "\n"


def _params(tmp_path: Path, text: str, name: str = "params.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# ---------------------------------------------------------------- YAML


def test_an_alias_bomb_is_refused_before_it_expands(tmp_path):
    path = _params(tmp_path, _alias_bomb() + "/**/imu_replayer:\n  ros__parameters:\n    topics: *i\n")
    assert len(path.read_bytes()) < 400
    tracemalloc.start()
    t0 = time.monotonic()
    try:
        with pytest.raises(ParameterError) as caught:
            load_params_file(path)
        seconds = time.monotonic() - t0
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    message = str(caught.value)
    assert seconds < 1.0 and peak < 5e6, (seconds, peak)  # 0.02 s beside two busy processes
    # 9 + 9**2 + ... values: level e (9**5) crosses the limit of 100 000, and is refused there
    assert message == (f"{path}: at line 6, column 8: alias *e expands the document past 100000 values: "
                       "refused")
    # an alias used before its anchor (the probe's layout) is an error of YAML already
    text = "/**/imu_replayer:\n  ros__parameters:\n    topics: *i\n" + _alias_bomb()
    with pytest.raises(ParameterError, match=r"not valid YAML at line 3, column 13: found undefined alias"):
        load_params_file(_params(tmp_path, text, "first.yaml"))
    # a cycle is refused; an alias within the bounds is what it names (yaml.safe_dump writes them)
    with pytest.raises(YamlRefusedError, match=r"alias \*a refers to a value that contains it"):
        load_yaml("a: &a {b: *a}")
    with pytest.raises(YamlRefusedError, match=r"alias \*a nests the document deeper than 64 levels"):
        load_yaml("a: &a [[[[1]]]]\nb: " + "[" * 60 + "*a" + "]" * 60)
    shared = [["x", "y"]] * 3
    assert load_yaml(yaml.safe_dump({"one": shared, "two": shared})) == {"one": shared, "two": shared}


def test_the_cli_refuses_an_alias_bomb_in_one_line_in_bounded_memory(tmp_path):
    ok = _params(tmp_path, "/**/orientation_filter:\n  ros__parameters:\n    max_gap_s: 1.0\n", "ok.yaml")
    code, _, err, ok_seconds, baseline = _cli_child("params", "--check", str(ok))
    assert code == 0 and err == ""
    bomb = _params(tmp_path, _alias_bomb() + "/**/imu_replayer:\n  ros__parameters:\n    topics: *i\n")
    code, out, err, seconds, peak = _cli_child("params", "--check", str(bomb), timeout=60)
    assert code == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"gait-biofeedback params: {bomb}: at line 6") and "alias *e expands" in err
    # refused in about the time a valid file takes (most of it the interpreter's start-up: 12 s each
    # beside two busy processes, where a fixed 10 s failed); a bomb that expanded would be killed at 60 s
    assert seconds < ok_seconds + 10 and peak < baseline + 30, (seconds, ok_seconds, peak, baseline)


@pytest.mark.parametrize(("text", "expected"), [
    ("[" * 5000, r"at line 1, column 65: nested deeper than 64 levels"),
    ("/**/imu_replayer:\n  ros__parameters:\n    topics: " + "[" * 5000 + "]" * 5000 + "\n",
     r"nested deeper than 64 levels"),
    ("{a: " * 3000 + "1" + "}" * 3000, r"nested deeper than 64 levels"),
])
def test_deep_nesting_is_refused_in_one_line(tmp_path, capsys, text, expected):
    path = _params(tmp_path, text)
    with pytest.raises(ParameterError, match=expected) as caught:
        load_params_file(path)
    assert "\n" not in str(caught.value)
    assert main(["params", "--check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and re.search(expected, err), err


def test_a_huge_value_is_refused_echoing_at_most_80_characters_of_it(tmp_path):
    for node, name, value in (("imu_replayer", "speed", "x" * 900_000),
                              ("imu_replayer", "speed", "[" + ", ".join(["1.5"] * 50_000) + "]"),
                              ("gait_events", "sides", "[" + ", ".join(["middle"] * 50_000) + "]")):
        path = _params(tmp_path, f"/**/{node}:\n  ros__parameters:\n    {name}: {value}\n")
        with pytest.raises(ParameterError, match=rf"parameter '{name}': got ") as caught:
            load_params_file(path)
        message = str(caught.value)
        for echoed in re.findall(r"got (.*?)(?: \(|; allowed)|\((.*?) not allowed\)", message):
            echoed = "".join(echoed)
            assert len(echoed) <= 80 and ("…" in echoed or "..." in echoed), echoed
        assert len(message) < 400 and "\n" not in message, message
    # an unknown parameter or node name: cut the same way
    path = _params(tmp_path, "/**/imu_replayer:\n  ros__parameters:\n    ? " + "y" * 500_000 + "\n    : 1\n")
    with pytest.raises(ParameterError, match="unknown parameter") as caught:
        load_params_file(path)
    assert len(str(caught.value)) < 1000
    path = _params(tmp_path, "? /**/" + "z" * 500_000 + "\n: {ros__parameters: {a: 1}}\n")
    with pytest.raises(ParameterError, match="unknown node") as caught:
        load_params_file(path)
    assert len(str(caught.value)) < 1000


def test_a_file_past_the_size_limit_is_refused_without_reading_it_whole(tmp_path):
    path = tmp_path / "big.yaml"
    with path.open("w") as f:
        f.write("/**/imu_replayer:\n  ros__parameters:\n    bag: '")
        f.truncate(MAX_BYTES * 50)  # 50 MiB of NUL bytes after the start: never read past 1 MiB + 1
    tracemalloc.start()
    try:
        with pytest.raises(ParameterError, match=rf"larger than the {MAX_BYTES} bytes accepted") as caught:
            load_params_file(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 4 * MAX_BYTES and "\n" not in str(caught.value)
    with pytest.raises(YamlRefusedError, match="larger than"):
        load_yaml("a: " + "x" * MAX_BYTES)
    with pytest.raises(YamlRefusedError, match="more than 100000 values"):
        load_yaml("[" + "0," * 150_000 + "]")


def test_every_loader_of_outside_files_refuses_an_alias_bomb(tmp_path, capsys):
    from gait_biofeedback.core.biofeedback.evaluator import load_targets
    from gait_biofeedback.io.bag_metadata import qos_from_text, read_metadata
    from gait_biofeedback.report.norms import load_norms

    bomb = _params(tmp_path, _alias_bomb(), "bomb.yaml")
    with pytest.raises(yaml.YAMLError, match="alias"):
        load_targets(bomb)
    with pytest.raises(ValueError, match="alias") as caught:
        load_norms(bomb)
    assert "\n" not in str(caught.value)
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text(_alias_bomb() + "rosbag2_bagfile_information: {version: 9}\n")
    assert read_metadata(bag) is None  # unreadable: rebuilt from the files by repair
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: &x {version: 9}\nother: *x\n")
    assert read_metadata(bag) == {"version": 9}
    assert qos_from_text(_alias_bomb()) == []
    csv = tmp_path / "walk.csv"
    csv.write_text("t,ax,ay,az\n0,0,0,9.8\n0.01,0,0,9.8\n")
    mapping = _params(tmp_path, _alias_bomb() + "chest: {acc: [ax, ay, az]}\n", "map.yaml")
    assert main(["import", "csv", str(csv), "--mapping", str(mapping), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "alias *e expands" in err and not (tmp_path / "o").exists()


def test_the_project_writes_yaml_without_aliases_so_it_reads_back(tmp_path):
    from gait_biofeedback.io.bag_metadata import TopicRecord, bag_metadata, read_metadata, write_metadata

    shared = [1, 2]
    document = {"a": shared, "b": shared}
    assert "*" not in dump_yaml(document) and "*" in yaml.safe_dump(document)
    qos = [{"history": "keep_last", "depth": 10}]
    topics = [TopicRecord("/a", "sensor_msgs/msg/Imu", qos), TopicRecord("/b", "sensor_msgs/msg/Imu", qos)]
    write_metadata(tmp_path, bag_metadata([], topics))
    info = read_metadata(tmp_path)
    assert info is not None and len(info["topics_with_message_count"]) == 2
    assert load_yaml_file(tmp_path / "metadata.yaml")["rosbag2_bagfile_information"]["version"] == 9


# ---------------------------------------------------------------- CSV import


def _rows_csv(path: Path, rows: int, time_column: bool = False) -> Path:
    """``rows`` rows of one sensor (acc m/s², gyr rad/s), a block of 10 000 random rows repeated."""
    rng = np.random.default_rng(0)
    block = rng.normal(size=(10_000, 6)) * [1, 1, 1, 0.5, 0.5, 0.5] + [0, 0, 9.81, 0, 0, 0]
    lines = [",".join(f"{v:.4f}" for v in row) for row in block]
    with path.open("w") as f:
        f.write(("t," if time_column else "") + "ax,ay,az,gx,gy,gz\n")
        for start in range(0, rows, len(lines)):
            n = min(len(lines), rows - start)
            if time_column:
                f.write("".join(f"{(start + k) / 100:.2f},{line}\n" for k, line in enumerate(lines[:n])))
            else:
                f.write("\n".join(lines[:n]) + "\n")
    return path


@pytest.mark.timeout(300)  # hang guards (and the child's 240 s): 53 s beside two busy processes
def test_a_csv_of_a_million_rows_imports_in_bounded_memory(tmp_path):
    from gait_biofeedback.io.bag_metadata import read_metadata

    rows = 1_000_000  # read whole it would take 1.1 GB more than 100,000 rows: far beyond the bound
    mapping = _params(tmp_path, "pelvis: {acc: [ax, ay, az], gyr: [gx, gy, gz]}\n", "map.yaml")
    peaks = {}
    for n in (100_000, rows):
        csv = _rows_csv(tmp_path / f"{n}.csv", n)
        code, out, err, seconds, peaks[n] = _cli_child("import", "csv", str(csv), "--mapping", str(mapping),
                                                       "--rate", "100", "-o", str(tmp_path / f"bag{n}"),
                                                       timeout=240)
        assert code == 0 and err == "" and "1 sensor (pelvis)" in out, err
    # reading it whole took 1.1 GB per million rows (genfromtxt, +2.2 GB here); streamed, the peak is about
    # the same for any size (measured 277 MB at 2 M rows, 10 M rows too)
    peak = peaks[rows]
    assert peak < min(peaks[100_000] + 200, 600), f"{peaks} MB peak by rows"
    assert read_metadata(tmp_path / f"bag{rows}")["message_count"] == rows
    print(f"\n{rows} rows ({csv.stat().st_size / 1e6:.0f} MB) imported in {seconds:.1f} s, peak {peak:.0f} "
          "MB")


def test_streamed_import_writes_the_same_bag_as_the_whole_file(tmp_path):
    """Chunks, a window smaller than the file, a gzip file: the bag's bytes are those of writing the
    whole recording; the warnings the same (the NaN count after the rows, once the file is read)."""
    from gait_biofeedback.io.bag import write_imu_bag
    from gait_biofeedback.io.importers import import_csv_to_bag, import_generic_csv

    rng = np.random.default_rng(1)
    n = 5000
    values = rng.normal(size=(n, 9))
    values[::500, 4] = np.nan
    lines = ["stamp;p_ax;p_ay;p_az;p_gx;p_gy;p_gz;c_ax;c_ay;c_az;note"]
    lines += [f"{1000 + 10 * k};" + ";".join("" if np.isnan(v) else f"{v:.5f}" for v in values[k]) + ";x"
              for k in range(n)]
    csv = tmp_path / "two.csv"
    csv.write_text("\n".join(lines) + "\n")
    mapping = {"time": "stamp", "units": {"time": "ms", "acc": "g"},
               "pelvis": {"acc": ["p_ax", "p_ay", "p_az"], "gyr": ["p_gx", "p_gy", "p_gz"]},
               "chest": {"acc": ["c_ax", "c_ay", "c_az"]}}
    whole = import_generic_csv(csv, mapping)
    write_imu_bag(tmp_path / "a" / "bag", whole.imu)
    said: list[str] = []
    import_csv_to_bag(csv, tmp_path / "b" / "bag", mapping, warn=said.append, block_chars=4096)
    assert said == whole.warnings and any("10 of 5000 samples contain NaN" in w for w in said)
    said.clear()
    import_csv_to_bag(csv, tmp_path / "c" / "bag", mapping, warn=said.append, block_chars=4096,
                      window_bytes=160 * 1000)
    assert said[-1] == "pelvis: 10 of 5000 samples contain NaN (kept; downstream filters skip them)"
    for name in ("bag_0.mcap", "metadata.yaml"):
        expected = (tmp_path / "a" / "bag" / name).read_bytes()
        assert (tmp_path / "b" / "bag" / name).read_bytes() == expected, name
        assert (tmp_path / "c" / "bag" / name).read_bytes() == expected, name


def test_a_bad_row_past_the_first_chunks_is_refused_and_nothing_is_left(tmp_path):
    from gait_biofeedback.io.importers import import_csv_to_bag

    csv = _rows_csv(tmp_path / "t.csv", 30_000, time_column=True)
    lines = csv.read_text().splitlines()
    mapping = {"pelvis": {"acc": ["ax", "ay", "az"], "gyr": ["gx", "gy", "gz"]}}
    same_time = f"{lines[25_001].split(',')[0]},0,0,9.8,0,0,0"
    for bad, expected in ((same_time, r"does not increase at data row 25001"),
                          ("250.01,0,0", r"line 25003 has 3 columns, the header 7")):
        csv.write_text("\n".join([*lines[:25_002], bad, *lines[25_003:]]) + "\n")
        with pytest.raises(ValueError, match=expected):
            import_csv_to_bag(csv, tmp_path / "out" / "bag", mapping, block_chars=50_000, window_bytes=80_000)
        assert not (tmp_path / "out").exists()  # the folders the import made are gone too


def test_a_bag_too_large_for_the_free_disk_is_refused_before_writing(tmp_path, capsys, monkeypatch):
    import shutil

    from gait_biofeedback.io import importers

    csv = _rows_csv(tmp_path / "t.csv", 20_000, time_column=True)
    mapping = _params(tmp_path, "pelvis: {acc: [ax, ay, az], gyr: [gx, gy, gz]}\n", "map.yaml")
    real = shutil.disk_usage
    monkeypatch.setattr(importers.shutil, "disk_usage", lambda p: real(p)._replace(free=1_500_000))
    argv = ["import", "csv", str(csv), "--mapping", str(mapping), "-o", str(tmp_path / "out")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and re.search(r"about 3\.\d MB \(20000 messages\) but the disk has 1\.5 MB "
                                              r"free", err), err
    assert not (tmp_path / "out").exists()
    monkeypatch.setattr(importers.shutil, "disk_usage", real)
    assert main(argv) == 0


@pytest.mark.parametrize("error", [MemoryError(), KeyError("acc"), RuntimeError("x" * 5000)])
def test_any_failure_of_an_import_ends_in_one_line(tmp_path, capsys, monkeypatch, error):
    from gait_biofeedback.io import importers

    def fail(*args, **kwargs):
        raise error

    monkeypatch.setattr(importers, "import_to_bag", fail)
    assert main(["import", "auto", str(tmp_path / "x.mat"), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and len(err) < 400, err
    assert ("not enough memory" in err) if isinstance(error, MemoryError) else type(error).__name__ in err


def test_an_endless_line_is_refused(tmp_path):
    from gait_biofeedback.io.importers import CSV_MAX_LINE, import_generic_csv

    csv = tmp_path / "x.csv"
    csv.write_text("t,ax,ay,az\n0,0,0," + "9" * (CSV_MAX_LINE + 10))
    with pytest.raises(ValueError, match=r"line 2 is longer than"):
        import_generic_csv(csv, {"chest": {"acc": ["ax", "ay", "az"]}})
    csv.write_text("t," + "a" * (CSV_MAX_LINE + 10) + "\n")
    with pytest.raises(ValueError, match=r"header line is longer than"):
        import_generic_csv(csv, {"chest": {"acc": ["ax", "ay", "az"]}})


# ---------------------------------------------------------------- dashboard


class _Log:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def warning(self, text: str) -> None:
        self.lines.append(text)

    info = error = warning


def _get(port: int, host: str, path: str = "/") -> tuple[int, bytes]:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    try:
        conn.putrequest("GET", path, skip_host=True)
        conn.putheader("Host", host)
        conn.endheaders()
        response = conn.getresponse()
        return response.status, response.read()
    finally:
        conn.close()


@pytest.mark.timeout(60)
def test_refused_hosts_are_logged_rate_limited_and_kept_nowhere(monkeypatch):
    from gait_biofeedback.dashboard import server as dashboard

    monkeypatch.setattr(dashboard, "REFUSAL_LOG_PERIOD", 1.0)
    log = _Log()
    server = dashboard.DashboardServer(lambda: None, lambda m: None, lambda: {}, port=0, logger=log)
    port = server.start()
    try:
        sizes = None
        for k in range(2000):
            status, body = _get(port, f"h{k}-" + "x" * 4000)
            assert status == 403 and len(body) < 300
            if k == 100:
                sizes = {name: len(v) for name, v in vars(server).items() if hasattr(v, "__len__")}
        grown = {name: len(v) for name, v in vars(server).items()
                 if hasattr(v, "__len__") and len(v) > sizes.get(name, 0)}
        assert server.refused == 2000 and not grown, grown
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and sum(_count(x) for x in log.lines) < 2000:
            time.sleep(0.05)
    finally:
        server.stop()
    # the first refusal at once, then a line per period with the count of those since: all accounted for
    assert log.lines[0].startswith("dashboard refused a request: Host 'h0-xxx")
    assert all(len(x) < 300 for x in log.lines) and len(log.lines) <= 2 + 2 * 60
    assert sum(_count(x) for x in log.lines) == 2000, log.lines


def _count(line: str) -> int:
    """The refusals a log line accounts for."""
    if found := re.search(r"refused (\d+) more request", line):
        return int(found.group(1))
    found = re.search(r"\((\d+) more refused since", line)
    return 1 + (int(found.group(1)) if found else 0)


@pytest.mark.timeout(60)
def test_the_number_of_connected_pages_is_bounded():
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    from gait_biofeedback.dashboard.server import DashboardServer

    log = _Log()
    server = DashboardServer(lambda: None, lambda m: None, lambda: {"type": "hello"}, port=0, logger=log,
                             max_clients=3)
    port = server.start()
    url = f"ws://127.0.0.1:{port}/ws"
    try:
        with contextlib.ExitStack() as pages:
            for _ in range(2):
                pages.enter_context(connect(url, open_timeout=5)).recv(timeout=5)
            with connect(url, open_timeout=5) as third:
                third.recv(timeout=5)
                with pytest.raises(InvalidStatus, match="503"):
                    connect(url, open_timeout=5)
                # the clinician's link still gets in: read-only pages cannot lock it out
                with connect(f"{url}?token={server.token}", open_timeout=5) as clinician:
                    assert json.loads(clinician.recv(timeout=5)).get("read_only") is False
            deadline = time.monotonic() + 5
            while server.clients > 2 and time.monotonic() < deadline:
                time.sleep(0.02)
            pages.enter_context(connect(url, open_timeout=5)).recv(timeout=5)  # room again
            assert server.clients == 3
    finally:
        server.stop()
    assert any("3 read-only pages are connected already" in line for line in log.lines)

"""``analyze`` outputs of this checkout against those of a git revision, byte for byte.

``.venv/bin/python benchmarks/regression.py --against REV [--keep DIR] [--only NAME ...]``

A change meant to keep behaviour (a speed-up, a move of code) must leave ``analyze``'s outputs the
same. Five reference recordings:

- ``clean``: a simulated training session (the demo's calibration, then walking laps), 60 s;
- ``no_mag``: the same without magnetometers;
- ``faults``: the clean one with a dropout, reordered samples, a spike, a stamp jump and a clock step;
- ``qmt``: ``../shared/data/qmt_fullbody`` imported, ``--calibrate-at 75:walking``;
- ``gaitmap``: ``../shared/data/gaitmap_example/imu_sample.csv`` imported, ``--calibrate-at auto``

(the real ones only where ``../shared/data`` is). Each is analysed by REV's code (a temporary git
worktree, run with this venv) and by this checkout's, each in a fresh process; the output folders'
files (the ``.mcap``, ``metadata.yaml``, ``calibration.yaml`` without its save time and digest) and
what ``analyze`` printed are compared; its Parquet tables (``tables/``, issue 46) and the line saying
so only when both sides wrote them (a revision before them has none). Prints one row per reference:
identical, or which file differs and where; exit 1 if any differs. ``--keep DIR`` leaves the inputs
and outputs there (an input already in DIR is reused).
"""

from __future__ import annotations

import argparse
import filecmp
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
DATA = HERE.parent / "shared" / "data"
CLI = ["-m", "gait_biofeedback.cli"]


def _cli(tree: Path, *argv: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(tree)}
    return subprocess.run([sys.executable, *CLI, *argv], cwd=tree, env=env, capture_output=True, text=True,
                          check=False)


def _faulty(clean: Path, output: Path) -> None:
    from gait_biofeedback.sim.faults import ClockStep, Dropout, Reorder, Spike, StampJump, write_faulty_bag

    write_faulty_bag(clean, output, [Dropout(20.0, 0.3), Reorder("left_shank", 25.0, 4),
                                     Spike("right_foot", 30.0), StampJump("pelvis", 35.0, 0.05),
                                     ClockStep("left_thigh", 40.0, 0.2)])


REFERENCES = ("clean", "no_mag", "faults", "qmt", "gaitmap")
"""The reference recordings' names (module docstring), for ``--only``."""


def inputs(folder: Path) -> dict[str, tuple[Path, list[str]]]:
    """Reference name → (recording, analyze's calibration arguments), made in ``folder`` if missing."""
    out: dict[str, tuple[Path, list[str]]] = {}
    for name, extra in (("clean", []), ("no_mag", ["--no-mag"])):
        bag = folder / name
        if not bag.exists():
            made = _cli(HERE, "simulate", "--scenario", "training", "--duration", "60", "--seed", "3", *extra,
                        "-o", str(bag))
            if made.returncode:
                raise RuntimeError(made.stderr)
        out[name] = (bag, ["--calibrate-at", "auto"])
    if not (folder / "faults").exists():
        _faulty(folder / "clean", folder / "faults")
    out["faults"] = (folder / "faults", ["--calibrate-at", "auto"])
    real = (("qmt", "qmt_fullbody", DATA / "qmt_fullbody" / "full_body_example_data.mat", ["--calibrate-at",
                                                                                           "75:walking"]),
            ("gaitmap", "gaitmap", DATA / "gaitmap_example" / "imu_sample.csv", ["--calibrate-at", "auto"]))
    for name, kind, source, calibrate in real:
        if not source.exists():
            continue
        bag = folder / name
        if not bag.exists():
            made = _cli(HERE, "import", kind, str(source), "-o", str(bag))
            if made.returncode:
                raise RuntimeError(made.stderr)
        out[name] = (bag, calibrate)
    return out


def _worktree(revision: str, where: Path) -> Path:
    tree = where / "rev"
    subprocess.run(["git", "-C", str(HERE), "worktree", "add", "--detach", str(tree), revision], check=True,
                   capture_output=True)
    return tree


def _comparable(path: Path) -> bytes:
    """A file's bytes, a calibration.yaml's without the lines that hold the wall-clock time it was saved
    at (``saved_at``) and the digest that covers it."""
    data = path.read_bytes()
    if path.name != "calibration.yaml":
        return data
    lines = data.splitlines(keepends=True)
    start = next((i for i, line in enumerate(lines) if line.startswith(b"digest:")), len(lines))
    end = next((i for i in range(start + 1, len(lines)) if not lines[i].startswith((b" ", b"-"))), len(lines))
    return b"".join(line for i, line in enumerate(lines)
                    if not line.startswith(b"saved_at:") and not start <= i < end)


TABLES = "tables"
"""``analyze``'s folder of Parquet tables (issue 46): compared when both sides have it."""


def _both_have_tables(a: Path, b: Path) -> bool:
    return (a / TABLES).is_dir() and (b / TABLES).is_dir()


def _without_tables_line(printed: str) -> str:
    lines = printed.splitlines(keepends=True)
    return "".join(line for line in lines if not line.startswith(f"wrote OUT/{TABLES}"))


def _difference(a: Path, b: Path) -> str | None:
    """None when the two output folders hold the same files with the same bytes (a calibration.yaml
    but for its save time, :func:`_comparable`; the tables folder's files too when both have it), else
    what differs."""
    names = sorted({p.name for p in a.iterdir()} | {p.name for p in b.iterdir()})
    for name in names:
        fa, fb = a / name, b / name
        if name == TABLES and not _both_have_tables(a, b):
            continue
        if fa.is_dir() and fb.is_dir():
            if (inner := _difference(fa, fb)) is not None:
                return f"{name}/{inner}"
            continue
        if not fa.exists() or not fb.exists():
            return f"{name} only in {'the revision' if fa.exists() else 'this checkout'}"
        if not filecmp.cmp(fa, fb, shallow=False):
            da, db = _comparable(fa), _comparable(fb)
            if da == db:
                continue
            at = next((i for i, (x, y) in enumerate(zip(da, db, strict=False)) if x != y),
                      min(len(da), len(db)))
            return f"{name} differs from byte {at} ({len(da)} / {len(db)} bytes)"
    return None


def main() -> int:
    """Run the comparison and print the table; 1 if any reference differs."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--against", required=True, metavar="REV", help="git revision to compare with")
    parser.add_argument("--keep", type=Path, default=None, help="folder for inputs and outputs (reused)")
    parser.add_argument("--only", nargs="*", choices=REFERENCES, help="reference names to run")
    args = parser.parse_args()
    work = args.keep or Path(tempfile.mkdtemp(prefix="regression_"))
    work.mkdir(parents=True, exist_ok=True)
    tree = None
    try:
        refs = inputs(work / "inputs")
        tree = _worktree(args.against, Path(tempfile.mkdtemp(prefix="regression_rev_")))
        failed = 0
        print(f"| reference | {args.against} vs this checkout |")
        print("|---|---|")
        for name, (bag, calibrate) in refs.items():
            if args.only and name not in args.only:
                continue
            outputs = {}
            for side, code_tree in (("rev", tree), ("here", HERE)):
                out = work / "outputs" / side / name  # one folder name: the .mcap is named after it
                shutil.rmtree(out, ignore_errors=True)
                run = _cli(code_tree, "analyze", str(bag), "-o", str(out), *calibrate)
                outputs[side] = (out, run.returncode, run.stdout.replace(str(out), "OUT"),
                                 run.stderr.replace(str(out), "OUT"))
            (a, ca, oa, ea), (b, cb, ob, eb) = outputs["rev"], outputs["here"]
            if not _both_have_tables(a, b):
                oa, ob = _without_tables_line(oa), _without_tables_line(ob)
            if (ca, oa, ea) != (cb, ob, eb):
                verdict = f"printed differently (exit {ca} / {cb})"
            elif ca != 0:
                verdict = f"both failed alike (exit {ca})"
            else:
                verdict = _difference(a, b) or "identical"
            failed += verdict != "identical"
            print(f"| {name} | {verdict} |", flush=True)
        return 1 if failed else 0
    finally:
        if tree is not None:
            subprocess.run(["git", "-C", str(HERE), "worktree", "remove", "--force", str(tree)], check=False,
                           capture_output=True)
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())

"""The clinician's report of three real recordings through the user's path, and how many pages each has.

``.venv/bin/python benchmarks/report_pages.py [--keep DIR]``

Issue 48's test: ipol_gait 7-4 (feet and lower back), hapt_waist user 20 run 1 (a waist phone) and
qmt_fullbody (8 sensors) each imported (``gait-biofeedback import``), analysed (``analyze
--calibrate-at auto``, qmt ``75:walking``) and reported (``report``) as a newcomer would, with no
parameter file; prints per recording its PDF's pages, the sections on each page, and the lines of the
summary. Needs ``../shared/data`` (its README); about 2 min on one core.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
DATA = HERE.parent / "shared" / "data"
RECORDINGS = {
    "ipol 7-4": ("ipol_gait", DATA / "ipol_gait" / "7-4.json", ["--calibrate-at", "auto"]),
    "hapt user 20": ("hapt", DATA / "hapt_waist" / "user20_run1.csv.gz", ["--calibrate-at", "auto"]),
    "qmt": ("qmt_fullbody", DATA / "qmt_fullbody" / "full_body_example_data.mat",
            ["--calibrate-at", "75:walking"]),
}
TITLES = ("Summary", "Progress across sessions", "Spatiotemporal parameters",
          "Gait Profile Score and Movement Analysis Profile", "Joint angles over the stride",
          "Strides over time", "Activity", "Calibration quality", "Data quality", "Time in the target band",
          "Sources")


def _cli(*argv: str) -> None:
    done = subprocess.run([sys.executable, "-m", "gait_biofeedback.cli", *argv], capture_output=True,
                          text=True, check=False)
    if done.returncode not in (0, 1):  # 1: analyze ran, with a warning the report shows
        raise SystemExit(f"{' '.join(argv[:2])} failed:\n{done.stderr[-2000:]}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--keep", type=Path, default=None,
                        help="leave the imports, analyses and reports here (imports there are reused)")
    args = parser.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} not found (the real recordings are not on this machine)")
        return 0
    import pypdf

    work = args.keep or Path(tempfile.mkdtemp(prefix="report_pages_"))
    print(f"{'recording':<14} {'pages':>5}  sections per page")
    for name, (kind, path, calibrate) in RECORDINGS.items():
        folder = work / name.replace(" ", "_")
        if not (folder / "raw" / "metadata.yaml").is_file():
            _cli("import", kind, str(path), "-o", str(folder / "raw"))
        _cli("analyze", str(folder / "raw"), "-o", str(folder / "analysis"), *calibrate, "--overwrite")
        _cli("report", str(folder / "analysis"), "-o", str(folder / "report"), "--overwrite")
        pages = [p.extract_text() for p in pypdf.PdfReader(str(folder / "report" / "report.pdf")).pages]
        layout = " | ".join(", ".join(t for t in TITLES if f"\n{t}\n" in f"\n{page}") for page in pages)
        print(f"{name:<14} {len(pages):>5}  {layout}")
        summary = pages[0].split("\nSummary\n", 1)[1]
        for title in TITLES:
            summary = summary.split(f"\n{title}\n")[0]
        for line in summary.split("• ")[1:]:
            print(f"{'':<22}• {' '.join(line.split())}")
    print(f"files in {work}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The documentation site (issue 51): it builds with warnings as errors, its API pages carry the
docstrings, the README stays a landing page, and no page of ``docs/`` and no docstring of
``gait_biofeedback/`` points at a file or a Python symbol that does not exist (``references.py``)."""

from __future__ import annotations

import ast
import html
import re
import subprocess
import sys
from pathlib import Path

from references import REPO, Reference, broken, broken_in_docstrings, broken_in_pages


def test_site_builds_with_warnings_as_errors_and_api_pages_from_the_docstrings(tmp_path: Path):
    site = tmp_path / "site"
    run = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site),
                          "--config-file", str(REPO / "mkdocs.yml")],
                         cwd=REPO, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-4000:]
    for page in (REPO / "docs").rglob("*.md"):  # every page built (a page left out of the nav warns)
        built = site / page.relative_to(REPO / "docs").with_suffix("") / "index.html"
        assert built.is_file() or page.name == "index.md", page
    # the batch API page shows estimate_orientation with the first sentence of its docstring, as the
    # source has it (read here with ast, not by the generator)
    source = ast.parse((REPO / "gait_biofeedback/core/orientation/filters/batch.py").read_text())
    function = next(n for n in source.body
                    if isinstance(n, ast.FunctionDef) and n.name == "estimate_orientation")
    first_words = " ".join(ast.get_docstring(function).split()[:6])
    page = (site / "api" / "batch" / "index.html").read_text()
    assert 'id="gait_biofeedback.batch.estimate_orientation"' in page
    text = re.sub(r"\s+", " ", html.unescape(re.sub(r"<[^>]+>", "", page)))
    assert first_words in text
    assert ":class:" not in text and ":func:" not in text  # the reST roles shown as Sphinx shows them
    assert "| `max_gap_s` |" not in (site / "parameters" / "index.html").read_text()  # a table, not raw text
    assert "<code>max_gap_s</code>" in (site / "parameters" / "index.html").read_text()
    assert "cdnjs" not in (site / "index.html").read_text()  # opens offline: nothing fetched from a CDN


def test_the_checker_finds_what_points_at_nothing():
    here = REPO / "gait_biofeedback" / "core"
    text = ("See DESIGN.md, io/session_bag.py, core/joints/alignment.py, docs/conventions.md and "
            "orientation.md; :class:`StreamSequencer`, :meth:`StreamSequencer.flush`, "
            ":meth:`StreamSequencer.rewind`, :func:`~gait_biofeedback.core.params.param`, "
            "``gait_biofeedback.core.params.RENAMED``, ``gait_biofeedback.core.params.RENAMD``, "
            ":mod:`.quaternion`, ``core/calibration/walk.py: stance_phases``, "
            "``core/calibration/walk.py: stance_phase``; output/mine/metadata.yaml and ../shared/data "
            "are not ours.")
    found = broken("t", text, here, module="gait_biofeedback.core.sequencer", owner=None)
    assert sorted(r.target for r in found) == sorted([
        "DESIGN.md", "io/session_bag.py", "StreamSequencer.rewind", "gait_biofeedback.core.params.RENAMD",
        "core/calibration/walk:stance_phase"])
    assert all(isinstance(r, Reference) for r in found)


def test_no_docstring_points_at_a_missing_file_or_symbol():
    assert [str(r) for r in broken_in_docstrings()] == []


def test_no_page_points_at_a_missing_file_or_symbol():
    assert [str(r) for r in broken_in_pages()] == []


def test_the_package_points_into_the_docs_not_at_readme_sections():
    naming_readme = [f"{path.relative_to(REPO)}:{n}"
                     for path in sorted((REPO / "gait_biofeedback").rglob("*.py"))
                     for n, line in enumerate(path.read_text().splitlines(), 1) if "README" in line]
    assert naming_readme == []


def test_readme_is_a_landing_page_whose_links_resolve():
    readme = (REPO / "README.md").read_text()
    assert len(readme.splitlines()) <= 200
    quick_start = readme.split("## Quick start", 1)[1].split("```", 2)[1]
    commands = [line.split()[:2] for line in quick_start.strip().splitlines()[1:]]
    assert commands == [["make", "demo"], ["make", "test"]]
    for node in ("imu_driver", "orientation_filter", "calibration", "joint_angles", "gait_events",
                 "activity_monitor", "biofeedback", "recorder"):
        assert f"| `{node}` |" in readme
    targets = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", readme)
    assert len(targets) >= 20
    assert [t for t in targets if not t.startswith("http") and not (REPO / t).exists()] == []

#!/usr/bin/env python3
"""Rewrite the parameter reference of the docs (docs/parameters.md, below its marker) from the stage
dataclasses (gait_biofeedback.parameters.parameter_reference; test_parameters.py checks the page)."""

from __future__ import annotations

from pathlib import Path

from gait_biofeedback.parameters import PARAMETER_PAGE_MARKER, parameter_reference

PAGE = Path(__file__).resolve().parents[1] / "docs" / "parameters.md"


def main() -> None:
    text = PAGE.read_text()
    head = text[:text.index(PARAMETER_PAGE_MARKER) + len(PARAMETER_PAGE_MARKER)]
    PAGE.write_text(head + "\n\n" + parameter_reference())


if __name__ == "__main__":
    main()

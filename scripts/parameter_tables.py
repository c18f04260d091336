#!/usr/bin/env python3
"""Rewrite the README's parameter tables from the stage dataclasses (test_parameters.py checks them)."""

from __future__ import annotations

from pathlib import Path

from gait_biofeedback.parameters import NODE_PARAMETERS, parameter_table

README = Path(__file__).resolve().parents[1] / "README.md"


def main() -> None:
    text = README.read_text()
    for node in NODE_PARAMETERS:
        start = text.index(f"#### `{node}`\n")
        end = text.index("\n\n", start)
        text = text[:start] + f"#### `{node}`\n" + "\n".join(parameter_table(node)) + text[end:]
    README.write_text(text)


if __name__ == "__main__":
    main()

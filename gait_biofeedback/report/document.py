"""The report as a list of sections of plain blocks (text, tables, SVG plots), built once and written
both as HTML (:mod:`.html`) and as PDF (:mod:`.pdf`), so the two have the same content."""

from __future__ import annotations

from dataclasses import dataclass, field

Cell = str | tuple[str, str]
"""A table cell: its text, or (text, status) with status "in", "low", "high", "warn", "bad" or ""."""


@dataclass
class Paragraph:
    text: str
    style: str = ""  # "", "note" (smaller), "small" (smallest: sources), "warning"


@dataclass
class Table:
    header: list[str]
    rows: list[list[Cell]]


@dataclass
class Figure:
    svg: str
    caption: str
    width: float = 1.0  # of the text width, centred (the PDF page; the HTML column)


@dataclass
class Bullets:
    items: list[str]
    style: str = ""  # "", "note" (small)


Block = Paragraph | Table | Figure | Bullets


@dataclass
class Section:
    title: str
    blocks: list[Block] = field(default_factory=list)
    new_page: bool = False

    def add(self, block: Block) -> Section:
        self.blocks.append(block)
        return self


@dataclass
class Document:
    title: str
    header: list[tuple[str, str]]
    sections: list[Section]


def cell_text(cell: Cell) -> str:
    return cell if isinstance(cell, str) else cell[0]


def cell_status(cell: Cell) -> str:
    return "" if isinstance(cell, str) else cell[1]

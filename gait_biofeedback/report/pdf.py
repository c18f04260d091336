"""A :class:`~gait_biofeedback.report.document.Document` as PDF, with fpdf2.

Why fpdf2 and not headless Chromium printing the HTML: it is pure Python, pinned with the rest, so a
report prints on any machine ``make setup`` made, without a browser (which a clinic's PC may lack and
this project's two-command set-up does not install); the plots are the same SVGs, drawn as vectors;
the text is real text (searchable, read back in the tests). The font is DejaVu Sans, shipped with
matplotlib, for °, ±, – and →.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import matplotlib
from fpdf import FPDF
from fpdf.fonts import FontFace

from gait_biofeedback.report.document import (
    Bullets,
    Document,
    Figure,
    Paragraph,
    Table,
    cell_status,
    cell_text,
)

FILL = {
    "in": (213, 245, 227),
    "low": (253, 235, 208),
    "high": (250, 219, 216),
    "warn": (252, 243, 207),
    "bad": (245, 183, 177),
}
FONT_DIR = Path(matplotlib.get_data_path()) / "fonts" / "ttf"
TITLE_MM = 10.0  # a section title with the space above it
_SVG_SIZE = re.compile(r'<svg[^>]*?width="([\d.]+)pt" height="([\d.]+)pt"')


def _figure_height(pdf: FPDF, figure: Figure) -> float:
    """The height (mm) ``figure`` takes on the page (its SVG's aspect at its width), 0 if unknown."""
    match = _SVG_SIZE.search(figure.svg)
    return pdf.epw * figure.width * float(match.group(2)) / float(match.group(1)) if match else 0.0


def _starts_on_this_page(pdf: FPDF, section) -> bool:
    """Whether ``section``'s title and its first block (a figure: all of it; else a few lines) fit
    below the cursor: a title is never left alone at the foot of a page."""
    first = section.blocks[0] if section.blocks else None
    needed = TITLE_MM + (_figure_height(pdf, first) + 8.0 if isinstance(first, Figure) else 12.0)
    return pdf.get_y() + needed <= pdf.page_break_trigger


class _Pdf(FPDF):
    def __init__(self, title: str) -> None:
        super().__init__(format="A4")
        self.report_title = title
        self.add_font("DejaVu", "", str(FONT_DIR / "DejaVuSans.ttf"))
        self.add_font("DejaVu", "B", str(FONT_DIR / "DejaVuSans-Bold.ttf"))
        self.set_auto_page_break(True, margin=15)

    def footer(self) -> None:
        self.set_y(-12)
        self.set_font("DejaVu", "", 7)
        self.cell(0, 5, f"{self.report_title} · page {self.page_no()}/{{nb}}", align="C")


def _table(pdf: _Pdf, table: Table) -> None:
    pdf.set_font("DejaVu", "", 7)
    with pdf.table(
        text_align="LEFT",
        first_row_as_headings=True,
        line_height=4,
        padding=0.8,
        headings_style=FontFace(emphasis="BOLD", fill_color=(238, 238, 238)),
    ) as t:
        row = t.row()
        for h in table.header:
            row.cell(h)
        for cells in table.rows:
            row = t.row()
            for c in cells:
                fill = FILL.get(cell_status(c))
                row.cell(cell_text(c), style=FontFace(fill_color=fill) if fill else None)
    pdf.ln(2)


def render_pdf(doc: Document, path: str | Path) -> Path:
    """Write ``doc`` to ``path``."""
    pdf = _Pdf(doc.title)
    pdf.add_page()
    pdf.set_font("DejaVu", "B", 15)
    pdf.cell(0, 9, doc.title, new_x="LMARGIN", new_y="NEXT")
    pdf.set_font("DejaVu", "", 8.5)
    for key, value in doc.header:
        pdf.set_font("DejaVu", "B", 8.5)
        pdf.cell(40, 4.5, key)
        pdf.set_font("DejaVu", "", 8.5)
        pdf.multi_cell(0, 4.5, value, new_x="LMARGIN", new_y="NEXT", align="L")
    for section in doc.sections:
        if section.new_page or not _starts_on_this_page(pdf, section):
            pdf.add_page()
        pdf.ln(3)
        pdf.set_font("DejaVu", "B", 11.5)
        pdf.cell(0, 7, section.title, new_x="LMARGIN", new_y="NEXT")
        for block in section.blocks:
            if isinstance(block, Paragraph):
                small = block.style == "small"
                pdf.set_font("DejaVu", "", 6.5 if small else 7.5 if block.style else 8.5)
                pdf.set_text_color(*((160, 80, 0) if block.style == "warning" else (60, 60, 60)))
                pdf.multi_cell(0, 3 if small else 4, block.text, new_x="LMARGIN", new_y="NEXT", align="L")
                pdf.set_text_color(0, 0, 0)
                pdf.ln(1)
            elif isinstance(block, Bullets):
                pdf.set_font("DejaVu", "", 6.5 if block.style else 8)
                for item in block.items:
                    pdf.multi_cell(0, 3.2 if block.style else 4, f"• {item}", new_x="LMARGIN", new_y="NEXT",
                                   align="L")
                pdf.ln(1)
            elif isinstance(block, Table):
                _table(pdf, block)
            elif isinstance(block, Figure):
                width = pdf.epw * block.width
                pdf.image(io.BytesIO(block.svg.encode()), x=pdf.l_margin + (pdf.epw - width) / 2, w=width)
                pdf.set_font("DejaVu", "", 7)
                pdf.multi_cell(0, 3.6, block.caption, new_x="LMARGIN", new_y="NEXT", align="L")
                pdf.ln(1)
    path = Path(path)
    pdf.output(str(path))
    return path

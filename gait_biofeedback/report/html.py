"""A :class:`~gait_biofeedback.report.document.Document` as one self-contained HTML file (inline CSS and
SVG, no script, nothing fetched: it opens offline and prints as it shows)."""

from __future__ import annotations

from html import escape

from gait_biofeedback.report.document import (
    Bullets,
    Document,
    Figure,
    Paragraph,
    Table,
    cell_status,
    cell_text,
)

CSS = """
body { font-family: "DejaVu Sans", Arial, sans-serif; font-size: 10pt; margin: 1.5em auto; max-width: 60em;
       color: #222; }
h1 { font-size: 16pt; margin-bottom: 0.2em; } h2 { font-size: 12.5pt; border-bottom: 1px solid #999;
     margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.6em 0; } th, td { border: 1px solid #bbb; padding: 2px 6px;
     text-align: left; vertical-align: top; } th { background: #eee; }
td.in { background: #d5f5e3; } td.low { background: #fdebd0; } td.high { background: #fadbd8; }
td.warn { background: #fcf3cf; } td.bad { background: #f5b7b1; }
table.header td { border: none; padding: 1px 12px 1px 0; }
p.note, ul.note { font-size: 8.5pt; color: #444; } p.small { font-size: 7.5pt; color: #444; }
p.warning { border-left: 4px solid #e67e22; padding-left: 8px; }
figure { margin: 0.6em 0; } figure svg { max-width: 100%; height: auto; } figcaption { font-size: 8.5pt; }
@media print { section.new-page { break-before: page; } }
"""


def _block(block) -> str:
    if isinstance(block, Paragraph):
        return f'<p class="{block.style}">{escape(block.text)}</p>'
    if isinstance(block, Bullets):
        items = "".join(f"<li>{escape(item)}</li>" for item in block.items)
        return f'<ul class="{block.style}">{items}</ul>'
    if isinstance(block, Figure):
        return (f'<figure style="max-width: {100 * block.width:.0f}%">{block.svg}'
                f"<figcaption>{escape(block.caption)}</figcaption></figure>")
    if isinstance(block, Table):
        head = "".join(f"<th>{escape(h)}</th>" for h in block.header)
        body = "".join(
            "<tr>"
            + "".join(f'<td class="{cell_status(c)}">{escape(cell_text(c))}</td>' for c in row)
            + "</tr>"
            for row in block.rows
        )
        return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
    raise TypeError(f"unknown block {type(block).__name__}")


def render_html(doc: Document) -> str:
    """The HTML text of ``doc``."""
    header = "".join(f"<tr><td><b>{escape(k)}</b></td><td>{escape(v)}</td></tr>" for k, v in doc.header)
    sections = "".join(
        f'<section class="{"new-page" if s.new_page else ""}"><h2>{escape(s.title)}</h2>'
        + "".join(_block(b) for b in s.blocks)
        + "</section>"
        for s in doc.sections
    )
    return (
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{escape(doc.title)}</title>'
        f"<style>{CSS}</style></head><body><h1>{escape(doc.title)}</h1>"
        f'<table class="header">{header}</table>{sections}</body></html>\n'
    )

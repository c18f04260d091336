"""MkDocs hook (mkdocs.yml ``hooks:``): the docstrings' reST roles shown as Sphinx shows them.

The docstrings cite symbols as ``:class:`~gait_biofeedback.core.sequencer.StreamSequencer```;
mkdocstrings renders the role's content as code and leaves the ``:class:`` before it. Here the role
goes, and a ``~`` target shows its last name only, as in Sphinx.
"""

from __future__ import annotations

import re
from typing import Any

_ROLE = re.compile(r":(?:func|class|meth|attr|data|mod|exc|obj):(<code>)")
_TILDE = re.compile(r"<code>~(?:[\w]+\.)*(\w+)</code>")


def on_page_content(html: str, **_: Any) -> str:
    return _TILDE.sub(r"<code>\1</code>", _ROLE.sub(r"\1", html))

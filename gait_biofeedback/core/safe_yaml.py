"""The one YAML loader for files from outside (params, targets, norms, mappings, bag metadata, ...).

PyYAML's safe loader with bounds, so that a small hostile file cannot exhaust memory or the stack:

* the text is at most ``max_bytes`` (1 MiB by default), checked before parsing (a file is read up to
  one byte past the limit, never whole);
* the document may have at most ``max_nodes`` (100 000) values and ``max_depth`` (64) levels, counted
  while composing, before the rest of the text is parsed, with every alias (``*name``, ``<<: *name``)
  counted as what it stands for: nested aliases that would expand exponentially ("billion laughs")
  are refused at the alias that crosses the limit, before anything is expanded (the constructed
  values share an aliased one, so memory follows the text). Aliases stay accepted because
  ``yaml.safe_dump`` writes them for a value met twice (a file edited with a script); one inside the
  value it names (a cycle) is refused.

A refusal is :class:`YamlRefusedError`, a :class:`yaml.MarkedYAMLError` (callers that catch
``yaml.YAMLError`` handle it unchanged) and a :class:`ValueError` (the command line prints it as one
line). :func:`describe` turns any YAML error into one short line. :func:`dump_yaml` writes YAML without
anchors or aliases, so that the project's own files always load again.

The C parser (libyaml) is used when PyYAML has it (4x faster, half the memory); composing, where the
bounds are checked, is PyYAML's Python code either way.
"""

from __future__ import annotations

import reprlib
from pathlib import Path
from typing import Any

import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.events import AliasEvent
from yaml.resolver import Resolver

MAX_BYTES = 1 << 20
"""Default size limit of a YAML text (params and config files are a few kB)."""
MAX_DEPTH = 64
MAX_NODES = 100_000
SHOWN_CHARS = 80
"""A refusal echoes at most this many characters of a value."""


def shown(value: Any, limit: int = SHOWN_CHARS) -> str:
    """``repr(value)`` cut to ``limit`` characters with an ellipsis (cheap for huge values)."""
    brief = reprlib.Repr()
    brief.maxstring = brief.maxother = limit
    brief.maxlist = brief.maxtuple = brief.maxdict = brief.maxset = max(limit // 4, 4)
    brief.maxlevel = 4
    return clip(brief.repr(value), limit)


def clip(text: str, limit: int = SHOWN_CHARS) -> str:
    """``text`` cut to ``limit`` characters with an ellipsis."""
    return text if len(text) <= limit else text[:limit - 1] + "…"


class YamlRefusedError(yaml.MarkedYAMLError, ValueError):
    """A YAML text refused by a bound (size, values, depth, a cyclic alias); ``problem`` says which."""

    def __init__(self, problem: str, mark: Any = None) -> None:
        super().__init__(problem=problem, problem_mark=mark)

    def __str__(self) -> str:
        return describe(self)


if getattr(yaml, "__with_libyaml__", False):
    from yaml.cyaml import CParser as _Parser
else:  # pragma: no cover - PyYAML built without libyaml
    from yaml.parser import Parser as _Parser
    from yaml.reader import Reader as _Reader
    from yaml.scanner import Scanner as _Scanner


class BoundedSafeLoader(Composer, _Parser, SafeConstructor, Resolver):
    """SafeLoader whose composer counts values and levels with every alias expanded, refusing the
    document past ``max_nodes`` or ``max_depth`` before anything is expanded (module docstring)."""

    def __init__(self, stream: Any, max_depth: int = MAX_DEPTH, max_nodes: int = MAX_NODES) -> None:
        if getattr(yaml, "__with_libyaml__", False):
            _Parser.__init__(self, stream)
        else:  # pragma: no cover
            _Reader.__init__(self, stream)
            _Scanner.__init__(self)
            _Parser.__init__(self)
        Composer.__init__(self)
        SafeConstructor.__init__(self)
        Resolver.__init__(self)
        self.max_depth, self.max_nodes = max_depth, max_nodes
        self._depth = self._nodes = 0
        self._heights = [0]  # per node being composed: the levels below it so far
        self._expanded: dict[int, tuple[int, int]] = {}  # id of an anchored node -> (values, levels)

    def compose_node(self, parent: Any, index: Any) -> Any:
        """One node; an alias counts as the values and levels of what it stands for."""
        event = self.peek_event()
        if isinstance(event, AliasEvent):
            node = self.anchors.get(event.anchor)
            if node is not None:  # (an undefined one is PyYAML's error)
                name = f"alias *{clip(str(event.anchor), 40)}"
                if id(node) not in self._expanded:
                    raise YamlRefusedError(f"{name} refers to a value that contains it: refused",
                                           event.start_mark)
                values, levels = self._expanded[id(node)]
                self._count(values, event.start_mark, f"{name} expands the document past")
                if self._depth + levels > self.max_depth:
                    raise YamlRefusedError(f"{name} nests the document deeper than {self.max_depth} levels: "
                                           "refused", event.start_mark)
                self._heights[-1] = max(self._heights[-1], levels)
            return super().compose_node(parent, index)
        self._count(1, event.start_mark, "more than")
        if self._depth >= self.max_depth:
            raise YamlRefusedError(f"nested deeper than {self.max_depth} levels: refused", event.start_mark)
        start = self._nodes
        self._depth += 1
        self._heights.append(0)
        try:
            node = super().compose_node(parent, index)
        finally:
            self._depth -= 1
            levels = self._heights.pop() + 1
        self._heights[-1] = max(self._heights[-1], levels)
        if event.anchor is not None:
            self._expanded[id(node)] = (self._nodes - start + 1, levels)
        return node

    def _count(self, values: int, mark: Any, problem: str) -> None:
        self._nodes += values
        if self._nodes > self.max_nodes:
            raise YamlRefusedError(f"{problem} {self.max_nodes} values: refused", mark)


def describe(exc: yaml.YAMLError) -> str:
    """One short line for a YAML error: ``at line L, column C: problem``."""
    mark = getattr(exc, "problem_mark", None)
    where = f"at line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
    problem = getattr(exc, "problem", None) or (str(exc).splitlines() or [type(exc).__name__])[0]
    return where + clip(" ".join(str(problem).split()), 2 * SHOWN_CHARS)


def load_yaml(text: str | bytes, *, max_bytes: int = MAX_BYTES, max_depth: int = MAX_DEPTH,
              max_nodes: int = MAX_NODES) -> Any:
    """The first YAML document of ``text`` (None if empty), within the bounds; raises
    :class:`YamlRefusedError` or another :class:`yaml.YAMLError`."""
    too_big = len(text) > max_bytes or (isinstance(text, str)
                                        and len(text.encode("utf-8", "surrogatepass")) > max_bytes)
    if too_big:
        raise YamlRefusedError(f"larger than the {max_bytes} bytes accepted: refused")
    loader = BoundedSafeLoader(text, max_depth, max_nodes)
    try:
        return loader.get_single_data()
    except RecursionError:  # a bound above the interpreter's stack: still one line
        raise YamlRefusedError("nested too deep: refused") from None
    except (ValueError, OverflowError) as exc:
        if isinstance(exc, yaml.YAMLError):
            raise
        raise YamlRefusedError(f"a value cannot be read: {exc}") from None  # e.g. an int of 5000 digits
    finally:
        loader.dispose()


def load_yaml_file(path: str | Path, *, max_bytes: int = MAX_BYTES, max_depth: int = MAX_DEPTH,
                   max_nodes: int = MAX_NODES) -> Any:
    """:func:`load_yaml` of a file, read at most ``max_bytes + 1`` bytes far (OSError if unreadable)."""
    with open(path, "rb") as handle:
        data = handle.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise YamlRefusedError(f"larger than the {max_bytes} bytes accepted: refused")
    return load_yaml(data, max_bytes=max_bytes, max_depth=max_depth, max_nodes=max_nodes)


class _NoAliasDumper(yaml.SafeDumper):
    def ignore_aliases(self, data: Any) -> bool:
        return True


def dump_yaml(data: Any, **options: Any) -> str:
    """``yaml.safe_dump(data, **options)`` without anchors or aliases (an object met twice is written
    twice), so that :func:`load_yaml` always reads it back."""
    return yaml.dump(data, Dumper=_NoAliasDumper, **options)

"""One instruction at a time (issue 49 item 4): the knowledge base's rule to say for a stride's cues.

The knowledge base (``config/instructions.yaml``, format documented there) maps a quantity outside its
band (below or above) to the words a therapist would say, each rule with its source and a priority.
The stroke gait-training literature feeds back a few quantities of the paretic side, one at a time
(issue 49; review: Front. Neurol. 2021, doi 10.3389/fneur.2021.637199), so :class:`InstructionSelector`
keeps one focus:

* on each stride, among its cues outside their band, the matching rule with the highest priority;
  ties go to the largest deviation, ``|error| / band width`` (band widths make angles, times and
  lengths comparable);
* hysteresis: a focus holds for at least ``hold_strides`` strides (either foot's, as they come)
  before another may take its place; after that the choice is made again among the quantities
  outside their band and the focus (if its own is still outside); when none is outside, the focus
  stays, in band (the schedule decides whether to say so), until another rule takes it;
* with ``paretic_side`` set, per-side quantities are fed back on the paretic side only, unless a rule
  names the other side (``non_paretic`` or that side); a rule on a bilateral quantity (a symmetry)
  names the leg its words speak of, and fires only for the paretic leg then;
* a rule for the ``paretic`` or ``non_paretic`` side is a stroke rule: without a paretic side it never
  fires (a healthy walker at 6 cm of foot lift was told "Lift your right foot higher as you swing it").

A rule naming a quantity no stage measures is refused, as a typo; one whose quantity a session does
not measure (a kit without thigh sensors: no trailing limb angle) simply never fires.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gait_biofeedback.core.biofeedback.evaluator import PARETIC_SIDES, QUANTITIES, SEVERITY_IN_BAND, Cue
from gait_biofeedback.core.safe_yaml import load_yaml_file, shown
from gait_biofeedback.core.segments import SIDES
from gait_biofeedback.resources import config_path

DIRECTIONS = ("below", "above")
RULE_SIDES = ("any", "paretic", "non_paretic", *SIDES)
_REQUIRED = ("id", "quantity", "direction", "priority", "text", "source")
_OPTIONAL = ("side",)
_ID = re.compile(r"[a-z][a-z0-9_]{0,63}")
MAX_RULES = 500
MAX_TEXT = 200


class KnowledgeBaseError(ValueError):
    """A knowledge base that is refused; the message names the rule and what is wrong."""


@dataclass(frozen=True)
class Rule:
    """One rule: ``text`` ({side} to fill) when ``quantity`` is ``direction`` of its band on ``side``."""

    id: str
    quantity: str
    direction: str
    priority: int
    text: str
    source: str
    side: str = "any"

    @property
    def bilateral(self) -> bool:
        return self.quantity in QUANTITIES and QUANTITIES[self.quantity][1]


def _rule(raw: Any, index: int) -> Rule:
    where = f"instructions: rule {index + 1}"
    if not isinstance(raw, Mapping):
        raise KnowledgeBaseError(f"{where}: a rule is a mapping of {', '.join(_REQUIRED)}; got {shown(raw)}")
    if isinstance(raw.get("id"), str):
        where += f" ({shown(raw['id'], 40)})"
    unknown = [k for k in raw if k not in _REQUIRED + _OPTIONAL]
    if unknown:
        raise KnowledgeBaseError(f"{where}: unknown key {shown(unknown[0], 40)}; a rule has "
                                 f"{', '.join(_REQUIRED + _OPTIONAL)}")
    missing = [k for k in _REQUIRED if raw.get(k) in (None, "")]
    if missing:
        raise KnowledgeBaseError(f"{where}: no {missing[0]}" + (" (each rule cites where it comes from)"
                                                                if missing[0] == "source" else ""))
    strings = {k: raw[k] for k in ("id", "quantity", "direction", "text", "source", "side") if k in raw}
    wrong = [k for k, v in strings.items() if not isinstance(v, str)]
    if wrong:
        raise KnowledgeBaseError(f"{where}: {wrong[0]} must be text; got {shown(raw[wrong[0]])}")
    rule_id, quantity, direction = raw["id"], raw["quantity"], raw["direction"]
    if not _ID.fullmatch(rule_id):
        raise KnowledgeBaseError(f"{where}: id {shown(rule_id, 40)} must be lower-case letters, digits "
                                 "and _ (at most 64)")
    if quantity not in QUANTITIES:
        raise KnowledgeBaseError(f"{where}: unknown quantity {shown(quantity, 40)}; "
                                 f"known: {', '.join(sorted(QUANTITIES))}")
    if direction not in DIRECTIONS:
        raise KnowledgeBaseError(f"{where}: direction {shown(direction, 40)}; use below or above (the band)")
    side = raw.get("side", "any")
    if side not in RULE_SIDES:
        raise KnowledgeBaseError(f"{where}: side {shown(side, 40)}; use one of {', '.join(RULE_SIDES)}")
    priority = raw["priority"]
    if isinstance(priority, bool) or not isinstance(priority, int) or not 1 <= priority <= 100:
        raise KnowledgeBaseError(f"{where}: priority {shown(priority)}; use a whole number from 1 to 100")
    text = " ".join(raw["text"].split())
    if len(text) > MAX_TEXT or re.search(r"[{}]", text.replace("{side}", "")):
        raise KnowledgeBaseError(f"{where}: text must be at most {MAX_TEXT} characters, with no braces "
                                 "but {side}")
    rule = Rule(rule_id, quantity, direction, priority, text, " ".join(raw["source"].split()), side)
    if "{side}" in text and rule.bilateral and side not in SIDES:
        raise KnowledgeBaseError(f"{where}: {quantity} is of both legs: name the leg the words speak of "
                                 "(side: left or right) to use {side}")
    return rule


def rules_from_dict(config: Any) -> tuple[Rule, ...]:
    """The rules of a parsed knowledge base; :class:`KnowledgeBaseError` for a malformed one."""
    if not isinstance(config, Mapping) or set(config) - {"rules"}:
        raise KnowledgeBaseError("instructions: the file holds one key, rules: a list of rules")
    raw = config.get("rules")
    if not isinstance(raw, list) or not raw:
        raise KnowledgeBaseError("instructions: rules must be a list of at least one rule")
    if len(raw) > MAX_RULES:
        raise KnowledgeBaseError(f"instructions: {len(raw)} rules; at most {MAX_RULES}")
    rules = tuple(_rule(r, i) for i, r in enumerate(raw))
    ids = [r.id for r in rules]
    twice = next((i for i in ids if ids.count(i) > 1), None)
    if twice:
        raise KnowledgeBaseError(f"instructions: id {twice!r} is given to two rules")
    return rules


def load_rules(path: str | Path = "") -> tuple[Rule, ...]:
    """The rules of a knowledge base file ('' = config/instructions.yaml)."""
    path = Path(path) if path else config_path("instructions.yaml")
    try:
        return rules_from_dict(load_yaml_file(path))
    except KnowledgeBaseError as exc:
        raise KnowledgeBaseError(f"{path}: {exc}") from None


@dataclass(frozen=True)
class Instruction:
    """The focus after a stride: ``rule``, its words for ``side`` (``text``), the latest ``cue`` of its
    quantity (in band or not), ``new`` when it took the focus on this stride, ``held``: strides so far."""

    rule: Rule
    side: str
    text: str
    cue: Cue
    new: bool
    held: int

    @property
    def outside(self) -> bool:
        """The quantity is outside its band on its latest stride."""
        return self.cue.severity != SEVERITY_IN_BAND


def deviation(cue: Cue) -> float:
    """``|error|`` in band widths (``|error|`` for a band of no width)."""
    width = cue.band_high - cue.band_low
    return abs(cue.error) / width if width > 0 else abs(cue.error)


class InstructionSelector:
    """The one instruction to give, stride by stride (module docstring)."""

    def __init__(self, rules: Iterable[Rule], hold_strides: int = 6, paretic_side: str = "none") -> None:
        if paretic_side not in PARETIC_SIDES:
            raise ValueError(f"paretic_side {paretic_side!r}; use one of {', '.join(PARETIC_SIDES)}")
        self.rules: dict[tuple[str, str], list[Rule]] = {}
        for rule in rules:
            self.rules.setdefault((rule.quantity, rule.direction), []).append(rule)
        self.hold_strides = hold_strides
        self.paretic_side = paretic_side
        self.focus: Instruction | None = None

    def _leg(self, rule: Rule, cue: Cue) -> str | None:
        """The leg ``rule``'s words speak of for ``cue`` ('' for none), None when it does not apply."""
        paretic = self.paretic_side
        if paretic == "none" and rule.side in ("paretic", "non_paretic"):
            return None  # a stroke rule (module docstring)
        other = "" if paretic == "none" else SIDES[1 - SIDES.index(paretic)]
        if cue.side:  # a per-side quantity
            if rule.side in SIDES:
                return cue.side if rule.side == cue.side else None
            if rule.side == "non_paretic":
                return cue.side if cue.side == other else None
            return cue.side if paretic in ("none", cue.side) else None
        if rule.side in SIDES:  # a bilateral quantity: the rule names the leg
            return rule.side if paretic in ("none", rule.side) else None
        if rule.side == "any":
            return ""
        leg = paretic if rule.side == "paretic" else other
        return leg or None

    def candidates(self, cues: Iterable[Cue]) -> list[tuple[Rule, str, Cue]]:
        """(rule, leg, cue) of every rule that applies to a cue outside its band."""
        out = []
        for cue in cues:
            if cue.severity == SEVERITY_IN_BAND or not math.isfinite(cue.error) or cue.error == 0.0:
                continue
            for rule in self.rules.get((cue.quantity, "below" if cue.error < 0 else "above"), ()):
                leg = self._leg(rule, cue)
                if leg is not None:
                    out.append((rule, leg, cue))
        return out

    def update(self, cues: Iterable[Cue]) -> Instruction | None:
        """The focus after one stride's ``cues`` (module docstring); None until a rule first applies."""
        cues = list(cues)
        focus = self.focus
        if focus is not None:
            latest = next((c for c in cues if (c.quantity, c.side) == (focus.cue.quantity, focus.cue.side)),
                          focus.cue)
            if focus.held < self.hold_strides:
                self.focus = Instruction(focus.rule, focus.side, focus.text, latest, False, focus.held + 1)
                return self.focus
            focus = Instruction(focus.rule, focus.side, focus.text, latest, False, focus.held)
        ranked = sorted(self.candidates(cues), key=lambda c: (c[0].priority, deviation(c[2])), reverse=True)
        if focus is not None and focus.outside:  # still to say: it competes with this stride's cues
            ranked.append((focus.rule, focus.side, focus.cue))
            ranked.sort(key=lambda c: (c[0].priority, deviation(c[2])), reverse=True)
        if not ranked:  # nothing outside: the focus, if any, stays (in band)
            self.focus = None if focus is None else Instruction(focus.rule, focus.side, focus.text, focus.cue,
                                                                 False, focus.held + 1)
            return self.focus
        rule, leg, cue = ranked[0]
        if focus is not None and (rule.id, leg) == (focus.rule.id, focus.side):
            self.focus = Instruction(rule, leg, focus.text, cue, False, focus.held + 1)
        else:
            self.focus = Instruction(rule, leg, rule.text.replace("{side}", leg), cue, True, 1)
        return self.focus

"""Total, linear, bounded JSON reading of model output.

Every role's answer (planner, judge, reflector, distiller, summarizer) is untrusted text: a weak or
looping model can write 100 kB of brackets, 5,000-deep nesting, a 10,000-digit integer or `NaN`.
Python's `json` module turns those into RecursionError, ValueError (int digit limit) or non-finite
floats, and re-scanning from every `{` makes extraction quadratic. The functions here:

- are total: any `str` gives a value or a `PlanParseError` (EB's "output_json_error"), nothing else;
- are linear: at each top-level `{` the C decoder is tried first (a valid answer costs one C
  parse); only when that fails is the object scanned once in Python (strings skipped whole by a
  regex) to find the nested `{` candidates, which are tried outermost first; each decode is bounded
  by the depth limit, so the work is at most `max_depth` times the text;
- are bounded: text past `max_chars` is cut, nesting past `max_depth` is an error, integers of more
  than `MAX_NUMBER_CHARS` digits, non-finite floats and the `NaN`/`Infinity` literals are refused,
  at most `MAX_CANDIDATES` candidate objects are tried and at most `MAX_TOKENS` brackets and strings
  are scanned in Python.

A candidate decodes here exactly when the old extractor's `json.loads` of the balanced `{...}` span
did, bounds apart (the C decoder stops at the matching `}`), so normal outputs parse as before.

`PlanParseError` stays in `worldmind_local.agent.plan` (callers catch it there); it is imported lazily
because plan.py delegates its extraction here.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "MAX_CHARS",
    "MAX_DEPTH",
    "MAX_NUMBER_CHARS",
    "MAX_CANDIDATES",
    "MAX_TOKENS",
    "extract_json_object",
    "extract_json_list",
    "parse_json",
]

MAX_CHARS = 200_000
MAX_DEPTH = 64
MAX_NUMBER_CHARS = 100
MAX_CANDIDATES = 1_000
MAX_TOKENS = 20_000  # brackets and strings scanned in objects that failed to decode, per call

_FENCE = re.compile(r"```(?:json|JSON)?")
# A whole JSON string (unrolled loop: linear, no nested repeats), a lone quote, a run of empty
# containers (one token: net depth 0, so `{}{}{}...` costs one step, not one per bracket), or a bracket.
_TOKEN = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"|"|(?:\{\}|\[\])+|[{}\[\]]', re.S)
_OPENERS = "{["


def _error(message: str) -> Exception:
    from worldmind_local.agent.plan import PlanParseError  # plan.py imports this module

    return PlanParseError(message)


def _parse_int(digits: str) -> int:
    """Refuse integers no plan needs: past 4,300 digits int() raises ValueError, and big ones are slow."""
    if len(digits) > MAX_NUMBER_CHARS:
        raise ValueError(f"integer of {len(digits)} digits")
    return int(digits)


def _parse_float(literal: str) -> float:
    """Finite floats only (`1e999` would otherwise become inf)."""
    if len(literal) > MAX_NUMBER_CHARS * 4:
        raise ValueError(f"number of {len(literal)} characters")
    value = float(literal)
    if not math.isfinite(value):
        raise ValueError(f"number {literal[:20]} is not a finite float")
    return value


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not JSON")


_DECODER = json.JSONDecoder(parse_int=_parse_int, parse_float=_parse_float, parse_constant=_reject_constant)


def _decode(text: str) -> Any:
    """json.loads with the bounds above; raises ValueError (RecursionError folded in) on anything bad."""
    try:
        return _DECODER.decode(text)
    except RecursionError as exc:  # the C decoder stops at the interpreter's recursion limit
        raise ValueError("JSON nested too deeply") from exc


def _decode_at(text: str, start: int) -> Any:
    """The JSON value that starts at `start` (C speed), or ValueError."""
    try:
        return _DECODER.raw_decode(text, start)[0]
    except RecursionError as exc:
        raise ValueError("JSON nested too deeply") from exc


def _depth_ok(value: Any, max_depth: int) -> bool:
    """Container nesting of a decoded value is at most `max_depth` (iterative: no recursion)."""
    stack = [(value, 1)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, (dict, list)):
            if depth > max_depth:
                return False
            children = node.values() if isinstance(node, dict) else node
            stack.extend((child, depth + 1) for child in children if isinstance(child, (dict, list)))
    return True


def _prepare(text: Any, max_chars: int) -> str:
    if not isinstance(text, str):
        raise _error(f"model output is {type(text).__name__}, not text")
    return text[:max_chars]


@dataclass
class _Region:
    """One top-level `{...}`: where it ends (-1: never closes) and every `{` inside with its `}`."""

    end: int = -1
    opens: list[int] = field(default_factory=list)
    ends: dict[int, int] = field(default_factory=dict)
    tokens: int = 0


def _scan_region(text: str, start: int, max_depth: int, budget: int) -> _Region:
    """One pass from the `{` at `start` to its matching `}`: strings are skipped whole (one regex
    token each), `{`/`[` nesting is counted against `max_depth`, and each `{` gets its `}`. More
    than `budget` tokens is an error: the scan is the only Python-speed part, so it is what we bound."""
    region, stack, depth = _Region(), [], 0
    for m in _TOKEN.finditer(text, start):
        region.tokens += 1
        if region.tokens > budget:
            raise _error(f"no usable JSON object within {MAX_TOKENS} brackets and strings")
        ch = m.group()
        if ch[0] == '"':
            if len(ch) == 1:  # an unterminated string: nothing after it can close the region
                return region
            continue
        if len(ch) > 1:  # empty containers: only the first `{}` can matter (it decodes to {})
            if depth + 1 > max_depth:
                raise _error(f"JSON nested deeper than {max_depth} levels")
            if (at := ch.find("{}")) != -1:
                region.opens.append(m.start() + at)
                region.ends[m.start() + at] = m.start() + at + 2
            continue
        if ch in _OPENERS:
            depth += 1
            if depth > max_depth:
                raise _error(f"JSON nested deeper than {max_depth} levels")
            if ch == "{":
                stack.append(m.start())
                region.opens.append(m.start())
        elif ch == "]":
            depth = max(depth - 1, len(stack))
        else:
            depth = max(depth - 1, len(stack) - 1)
            region.ends[stack.pop()] = m.end()
            if not stack:
                region.end = m.end()
                return region
    return region


def _first_object(text: str, start: int, max_depth: int) -> dict[str, Any] | None:
    """Fast path: the object that opens at `start` when it decodes as is (the common case)."""
    try:
        value = _decode_at(text, start)
    except ValueError:
        return None
    return value if isinstance(value, dict) and _depth_ok(value, max_depth) else None


def extract_json_object(text: str, *, max_chars: int = MAX_CHARS, max_depth: int = MAX_DEPTH) -> dict[str, Any]:
    """The first balanced JSON object in `text`, ignoring code fences and prose around it.

    Candidates are tried in the order their `{` appears; an object that does not decode is skipped
    and the next `{` tried (so `{bad} {"ok": 1}` gives `{"ok": 1}`); a `{` that never closes ends the
    search ("output cut off"). Outside an object only `{` matters (quotes in prose are ignored).
    Raises PlanParseError only.
    """
    cleaned = _FENCE.sub("", _prepare(text, max_chars))
    tried, budget, pos = 0, MAX_TOKENS, cleaned.find("{")
    while pos != -1:
        found = _first_object(cleaned, pos, max_depth)
        if found is not None:
            return found
        region = _scan_region(cleaned, pos, max_depth, budget)
        budget -= region.tokens
        if region.end == -1:
            raise _error("no complete JSON object (output cut off?)")
        for open_at in region.opens[1:]:  # the outer one just failed; try the nested ones in order
            tried += 1
            if tried > MAX_CANDIDATES:
                raise _error(f"no JSON object among the first {MAX_CANDIDATES} candidates")
            try:
                value = _decode(cleaned[open_at:region.ends[open_at]])
            except ValueError:
                continue
            if isinstance(value, dict):
                return value
        tried += 1
        if tried > MAX_CANDIDATES:
            raise _error(f"no JSON object among the first {MAX_CANDIDATES} candidates")
        pos = cleaned.find("{", region.end)
    raise _error("no JSON object in the output")


def parse_json(text: str, *, max_chars: int = MAX_CHARS, max_depth: int = MAX_DEPTH) -> Any:
    """The whole of `text` as one JSON value (any type), with the same bounds. A text longer than
    `max_chars` is refused rather than cut (cutting a whole document only makes it invalid)."""
    if isinstance(text, str) and len(text) > max_chars:
        raise _error(f"JSON text of {len(text)} characters (limit {max_chars})")
    prepared = _prepare(text, max_chars)
    try:
        value = _decode(prepared)
    except ValueError as exc:
        msg = exc.msg if isinstance(exc, json.JSONDecodeError) else str(exc)
        raise _error(f"not valid JSON ({msg})") from None
    if not _depth_ok(value, max_depth):
        raise _error(f"JSON nested deeper than {max_depth} levels")
    return value


def extract_json_list(text: str, *, max_chars: int = MAX_CHARS, max_depth: int = MAX_DEPTH) -> list[Any]:
    """A bare JSON list: from the first `[` to the last `]` (fences and prose around it ignored)."""
    cleaned = _FENCE.sub("", _prepare(text, max_chars))
    start, end = cleaned.find("["), cleaned.rfind("]")
    if start == -1 or end <= start:
        raise _error("no JSON list in the output")
    value = parse_json(cleaned[start:end + 1], max_chars=max_chars, max_depth=max_depth)
    if not isinstance(value, list):
        raise _error("the bracketed text is not a JSON list")
    return value

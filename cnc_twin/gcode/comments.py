"""A block's comment as LinuxCNC acts on it: ``(msg,...)`` a message to the operator,
``(debug,...)`` / ``(print,...)`` / ``(log...)`` with parameter values put in, any other comment
kept as it is.

Only the block's last comment counts (LinuxCNC keeps one per block). The keyword before the comma
is read in any case (``(MSG, x)``), the text after it is kept as written. In ``debug``, ``print``
and ``log`` texts, ``#n`` and ``#<name>`` become their values with six decimals; a name not set
reads 0.
"""

from __future__ import annotations

import re

from cnc_twin.gcode.expressions import Parameters

_KIND = re.compile(r"^(msg|debug|print|logopen|logappend|logclose|log),?", re.IGNORECASE)
_PARAMETER = re.compile(r"#(\d+|<[^>]*>)")
SUBSTITUTED = frozenset(("debug", "print", "log"))
"""kinds whose text has parameter values put in"""
CALLS = {"msg": "MESSAGE", "debug": "MESSAGE", "log": "LOG", "logopen": "LOGOPEN", "logappend": "LOGAPPEND",
         "logclose": "LOGCLOSE"}
"""kind -> the canonical call it makes (``print`` writes to the console instead)"""


def _value(params: Parameters, key: str) -> float:
    if key.startswith("<"):
        name = "".join(key[1:-1].split()).lower()
        return params.name(name) if params.has_name(name) else 0.0
    return params.number(int(key))


def read_comment(text: str, params: Parameters) -> tuple[str, str]:
    """``(kind, text)`` for a comment's text: kind is ``comment``, ``print`` or a key of
    :data:`CALLS`; text is what the call carries."""
    match = _KIND.match(text)
    if match is None or (match.group(0)[-1] != "," and match.group(1).lower() != "logclose"):
        return "comment", text
    kind = match.group(1).lower()
    body = text[match.end():]
    if kind in SUBSTITUTED:
        body = _PARAMETER.sub(lambda m: f"{_value(params, m.group(1)):.6f}", body)
    return kind, body

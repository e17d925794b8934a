"""A block's comment as LinuxCNC acts on it: ``(msg,...)`` a message to the operator,
``(debug,...)`` / ``(print,...)`` / ``(log...)`` with parameter values put in, any other comment
kept as it is.

Only the block's last comment counts (LinuxCNC keeps one per block). The keyword before the comma
is read in any case (``(MSG, x)``), the text after it is kept as written. In ``debug``, ``print``
and ``log`` texts, ``#n`` and ``#<name>`` become their values with six decimals (a value within
1e-4 of 0 as 0), a name not set or a number past the last parameter ``######``, as LinuxCNC
writes them. A ``(debug,...)`` says nothing while ``#5599`` is 0 or less.
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


PARAMETER_SLOTS = 5602
"""LinuxCNC's parameter array: a comment may show ``#0`` .. ``#5601``"""
DEBUG_SWITCH = 5599
"""``(debug,...)`` messages are shown while this parameter is above 0 (1 at the start)"""
NEAR_ZERO = 1e-4
"""a value this close to 0 is shown as 0 (LinuxCNC's equal(), so no ``-0.000000``)"""


def _value(params: Parameters, key: str) -> str:
    if key.startswith("<"):
        name = "".join(key[1:-1].split()).lower()
        if not params.has_name(name):
            return "######"
        value = params.name(name)
    else:
        index = int(key)
        if index >= PARAMETER_SLOTS:
            return "######"
        value = params.number(index)
    return f"{0.0 if abs(value) < NEAR_ZERO else value:.6f}"


def read_comment(text: str, params: Parameters) -> tuple[str, str]:
    """``(kind, text)`` for a comment's text: kind is ``comment``, ``print``, ``silent`` (a
    debug message switched off) or a key of :data:`CALLS`; text is what the call carries."""
    match = _KIND.match(text)
    if match is None or (match.group(0)[-1] != "," and match.group(1).lower() != "logclose"):
        return "comment", text
    kind = match.group(1).lower()
    body = text[match.end():]
    if kind in SUBSTITUTED:
        body = _PARAMETER.sub(lambda m: _value(params, m.group(1)), body)
    if kind == "debug" and not params.number(DEBUG_SWITCH) > 0.0:
        return "silent", body
    return kind, body

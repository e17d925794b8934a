"""The six machine axes, their order and kinds; the one place that fixes them.

Every per-axis array in the code base (shape ``(6,)``) is in this order.
"""

AXES: tuple[str, ...] = ("X", "Y", "Z", "A", "B", "C")
LINEAR_AXES: frozenset[str] = frozenset({"X", "Y", "Z"})
ROTARY_AXES: frozenset[str] = frozenset({"A", "B", "C"})
N_AXES = len(AXES)

HOME_KEYFRAME = "home"
"""the MJCF keyframe every run starts from (the axes' power-on positions)"""

SWITCH_HOME, SWITCH_LIMIT_POS, SWITCH_LIMIT_NEG = 1, 2, 4
"""bits of an axis's switch inputs, as the machine wires them to the card's digital inputs"""


def is_rotary(axis: str) -> bool:
    """True for A/B/C (positions in rad inside, deg in scenarios)."""
    return axis in ROTARY_AXES


def joint_name(axis: str) -> str:
    """MJCF joint driven by ``axis``, e.g. ``"X" -> "x_joint"``."""
    return f"{axis.lower()}_joint"


def actuator_name(axis: str) -> str:
    """MJCF actuator (the servo amplifier) of ``axis``, e.g. ``"X" -> "x_drive"``."""
    return f"{axis.lower()}_drive"


def motor_joint_name(axis: str) -> str:
    """MJCF hinge of ``axis``'s motor rotor in a compliant machine, e.g. ``"X" -> "x_motor"``
    (absent in a rigid one, where the drive turns the axis joint itself)."""
    return f"{axis.lower()}_motor"

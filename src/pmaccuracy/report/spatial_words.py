"""Words of a spatial robot's error sources, shared by the sections of its accuracy report
(:mod:`pmaccuracy.report.spatial_report`, :mod:`pmaccuracy.report.spatial_design`): a source's label
(``legs[2].joints[1].radial[pin 1]``) in words, its kind (joint and key, whatever the leg) and its unit.
"""

from __future__ import annotations

import re

from ..model.spatial_sources import ACTUATED, JOINT_WORDS, JOINTS

#: Joint roles of each architecture, base to platform (the sources' table says which joint a label is).
ROLES = {"6-UPS": ("base", "actuated", "platform"), "3-RPS": ("base", "actuated", "platform"),
         "3-PRS": ("actuated slide", "carriage", "platform"), "3-UPU": ("base", "actuated", "platform"),
         "delta": ("arm", "elbow, rod 1", "platform, rod 1", "elbow, rod 2", "platform, rod 2")}
#: Words of the source keys.
KEY_WORDS = {"radial": "radial play", "axial": "axial play", "tilt": "tilt", "actuator": "actuator error",
             "backlash": "backlash", "lateral": "lateral play", "position": "position tolerance",
             "direction": "direction tolerance", "length": "length tolerance"}
_LABEL = re.compile(r"legs\[(\d+)\]\.joints\[(\d+)\]\.(\w+)(?:\[pin (\d)\])?")


def source_description(architecture: str, label: str) -> str:
    """``legs[2].joints[1].radial[pin 1]`` in words: ``leg 2, universal joint (base), radial play, pin 1``
    (a label of another form, or of an architecture without named joints, is returned as it is)."""
    m = _LABEL.fullmatch(label)
    if not m or architecture not in JOINTS:
        return label
    leg, joint, key, pin = int(m[1]), int(m[2]) - 1, m[3], m[4]
    kind = JOINTS[architecture][joint]
    word = "actuated " + JOINT_WORDS[kind] if joint == ACTUATED[architecture] and kind != "P" else JOINT_WORDS[kind]
    role = ROLES[architecture][joint]
    text = f"leg {leg}, {word} ({role}), {KEY_WORDS.get(key, key)}"
    return text + (f", pin {pin}" if pin else "")


def kind_of(architecture: str, label: str) -> str:
    """The kind of a source, whatever its leg and pin: ``universal joint (base), radial play`` for
    ``legs[2].joints[1].radial[pin 1]`` (the label itself when it is of another form)."""
    m = _LABEL.fullmatch(label)
    if not m or architecture not in JOINTS:
        return label
    return source_description(architecture, f"legs[1].joints[{m[2]}].{m[3]}").split(", ", 1)[1]


def is_angle(architecture: str, joint: int, key: str, spec: tuple | None = None) -> bool:
    """Whether the half-width ``key`` of joint ``joint`` (0-based) is an angle (rad): a tilt, a direction
    tolerance, the actuator error of a Delta's arm or of an actuated revolute joint."""
    if key in ("tilt", "direction"):
        return True
    if key != "actuator":
        return False
    if architecture == "delta":
        return True
    kinds, actuated = (spec[0], spec[1]) if spec is not None else (JOINTS.get(architecture, ()),
                                                                    ACTUATED.get(architecture, -1))
    return joint == actuated and joint < len(kinds) and kinds[joint] == "R"

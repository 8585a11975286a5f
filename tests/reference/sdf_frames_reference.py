"""Independent reference of SDFormat frames (tests only; imports nothing from ``pmaccuracy``).

The pose of a link, joint or ``<frame>`` of an SDF model in the model frame, following the SDFormat 1.7+
rules written out from the specification: a ``<pose>`` ``x y z roll pitch yaw`` (``degrees="true"``: in
degrees) is relative to its ``relative_to`` frame, by default the model frame for a link, the child link for a
joint, the ``attached_to`` frame (else the model frame) for a ``<frame>``. Rotations by scipy
(``Rotation.from_euler("xyz", [roll, pitch, yaw])`` is ``Rz(yaw) Ry(pitch) Rx(roll)``, SDF's fixed axes).
Positions in metres.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
from scipy.spatial.transform import Rotation


def model_of(path) -> ET.Element:
    """The model with joints of an SDF file (under ``<sdf>`` or ``<sdf><world>``)."""
    root = ET.parse(path).getroot()
    models = root.findall("model") + root.findall("world/model")
    return next(m for m in models if m.find("joint") is not None)


def pose_in_model(model: ET.Element, name: str) -> tuple[np.ndarray, Rotation]:
    """``(position m, rotation)`` of the link, joint or frame ``name`` in the model frame."""
    if name == "__model__":
        return np.zeros(3), Rotation.identity()
    el = next(e for tag in ("link", "joint", "frame") for e in model.findall(tag) if e.get("name") == name)
    pose = el.find("pose")
    values = np.zeros(6) if pose is None or not (pose.text or "").strip() else \
        np.array([float(v) for v in pose.text.split()])
    if pose is not None and pose.get("degrees") == "true":
        values[3:] = np.radians(values[3:])
    if pose is not None and pose.get("relative_to"):
        parent = pose.get("relative_to")
    elif el.tag == "joint":
        parent = el.findtext("child").strip()
    elif el.tag == "frame":
        parent = el.get("attached_to") or "__model__"
    else:
        parent = "__model__"
    p0, R0 = pose_in_model(model, parent)
    return p0 + R0.apply(values[:3]), R0 * Rotation.from_euler("xyz", values[3:])

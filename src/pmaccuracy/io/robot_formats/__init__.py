"""Robot files of other tools: MuJoCo MJCF (loops closed by ``<equality><connect/>``), URDF with loop closures and
SDFormat (loops closed by the joints beyond a spanning tree).

Reading goes through the ecosystem's own parsers: the ``mujoco`` package compiles an MJCF file (frames,
``childclass``, quaternions, Euler angles, ``<compiler angle=...>`` are MuJoCo's business) and its kinematics at the
reference configuration ``qpos0`` give every joint's world anchor and axis; ``yourdfpy`` reads a URDF and its
forward kinematics at zero joint values give the link frames; an SDF file is XML read with the standard library (no
maintained SDFormat reader is on PyPI), its ``relative_to`` frames resolved by :func:`read_sdf`. Each becomes a
neutral graph (:class:`KinematicGraph`): rigid groups of bodies (bodies welded together or with no joint of their
own are one group), joined by joints (hinge, slide, ball) and loop closures (a closure is a ball joint at its
anchor). The legs are the connected pieces left when the base (the world's group) and the platform (the group that
most legs reach) are taken away; the joints along each leg, merged into kinematic pairs (two hinges through one
point make a universal joint ``U``, three or a ball a spherical joint ``S``), give its pattern: ``UPS`` or ``SPS``
(6-UPS), ``RPS``, ``PRS``, ``UPU``, or an actuated hinge with two ``SS`` rods (the Delta's R(SS)2).

Units: the files' metres become mm, radians stay radians inside (degrees in our TOML). The platform frame is the
platform body's frame, the home pose its pose at the reference configuration, the base frame the world's (or that of
the one fixed body under the world that carries the legs). Actuated joint values are MuJoCo's joint values where our
model has the same coordinate (a Delta's arm angle, a 3-PRS carriage); a leg length (6-UPS, 3-RPS, 3-UPU) is the
reference length plus the slide's travel from its ``ref``.

Writing: :func:`write_mjcf`, :func:`write_urdf` and :func:`write_sdf` give fresh files of any spatial robot (the
exporter shapes: a free platform closed by one connect per ball, URDF+ ``<loop>`` elements, SDF ball joints),
:func:`export_into` writes a calibrated robot into the file it came from, changing only positions, axes, joint
references and the actuated ranges. Non-kinematic data of our format (name, description, cones, radii, joint-cone
axes) ride along in an MJCF ``<custom><text name="pmaccuracy">`` (a URDF ``<pmaccuracy>`` element, an SDF
``<pmaccuracy:extras>``) as JSON.
"""

from .calibrated import export_into
from .graph import EXTRAS_NAME, PATTERNS, SUFFIXES, FileJoint, KinematicGraph, is_robot_file
from .mjcf import read_mjcf
from .recognise import Pair, pairs_of, planar_from_graph, read_robot_file, robot_from_graph
from .sdf import SDF_NAMESPACE, actuated_joints, read_sdf
from .urdf import read_urdf
from .write import mjcf_tree, sdf_tree, urdf_tree, write_mjcf, write_sdf, write_urdf

__all__ = ["EXTRAS_NAME", "PATTERNS", "SDF_NAMESPACE", "SUFFIXES", "FileJoint", "KinematicGraph", "Pair",
           "actuated_joints", "export_into", "is_robot_file", "mjcf_tree", "pairs_of", "planar_from_graph",
           "read_mjcf", "read_robot_file", "read_sdf", "read_urdf", "robot_from_graph", "sdf_tree", "urdf_tree",
           "write_mjcf", "write_sdf", "write_urdf"]

"""Robots from and to SDFormat files (``pmaccuracy.io.robot_formats.sdf``).

``tests/data/formats/hexapod.sdf`` and ``delta.sdf`` were written by hand (a Gazebo world with nested
``relative_to`` frames and one closing ball joint per leg; a Delta drawn once per leg in turned mount frames),
beside the hand-written TOML of the same robots. Checked here:

* every spatial preset written as SDF and read back is the same robot (every leg key to 1e-9, the same inverse
  kinematics at random poses to 1e-9);
* each hand-written file imports to its TOML's kinematics (1e-9), the hexapod's leg lengths equal the closed
  form ``|p + R b - A|`` from the TOML numbers (scipy's rotations);
* SDF's pose convention (``R = Rz(yaw) Ry(pitch) Rx(roll)``, quaternions ``x y z w``) and axis frames (the joint
  frame by default; SDF 1.6's ``use_parent_model_frame``): the hexapod with each piston's link turned so that its
  slide is its z-axis, the turns computed here with scipy (``from_euler("xyz")``, ``as_quat``), imports to the
  same robot;
* a calibrated robot written into the hand-written file changes only the geometry: the file's other elements are
  untouched, and the poses read back here with scipy put the joints at the calibrated geometry (1e-9 mm);
* bad files end the CLI with status 2 and one line naming the file and the element.
"""

from __future__ import annotations

import dataclasses
import re
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli
from scipy.spatial.transform import Rotation

import pmaccuracy as pm
from robot_compare import assert_same_robot, random_poses
import sdf_frames_reference
from pmaccuracy.kinematics.spatial import inverse_kinematics
from pmaccuracy.model.spatial import SpatialManipulator

rf = pytest.importorskip("pmaccuracy.io.robot_formats")

DATA = Path(__file__).parents[1] / "data" / "formats"
PRESETS = SpatialManipulator.preset_names()


def _same_kinematics(imported, written, tol=1e-9):
    assert imported.architecture == written.architecture
    np.testing.assert_allclose(imported.home, written.home, atol=tol, rtol=0)
    for la, lb in zip(imported.legs, written.legs):
        np.testing.assert_allclose(la.base, lb.base, atol=tol, rtol=0)
        np.testing.assert_allclose(la.platform, lb.platform, atol=tol, rtol=0)
        np.testing.assert_allclose(la.stroke, lb.stroke, atol=tol, rtol=0)
    poses = random_poses(written, seed=3)
    q = inverse_kinematics(imported, poses).q
    assert np.all(np.isfinite(q))
    np.testing.assert_allclose(q, inverse_kinematics(written, poses).q, atol=tol, rtol=0)
    return poses, q


def _ups_lengths(toml_path, poses):
    """Leg lengths |p + R b - A| from the TOML numbers (scipy's rotation of the rotation vector)."""
    data = tomllib.loads(Path(toml_path).read_text())
    A = np.array([leg["base"] for leg in data["legs"]])
    b = np.array([leg["platform"] for leg in data["legs"]])
    R = Rotation.from_rotvec(poses[:, 3:]).as_matrix()
    B = poses[:, None, :3] + np.einsum("nij,lj->nli", R, b)
    return np.linalg.norm(B - A, axis=-1)


@pytest.mark.parametrize("name", PRESETS)
def test_every_spatial_preset_survives_an_sdf_round_trip(name, tmp_path):
    robot = SpatialManipulator.preset(name)
    path = rf.write_sdf(robot, tmp_path / f"{name}.sdf")
    back = pm.load_robot(path)
    assert_same_robot(robot, back)
    assert back.name == robot.name and back.description == robot.description


@pytest.mark.parametrize("stem", ["hexapod", "delta"])
def test_hand_written_sdf_files_import_to_their_hand_written_toml(stem):
    imported = pm.load_robot(DATA / f"{stem}.sdf")
    written = pm.load_robot(DATA / f"{stem}.toml")
    poses, q = _same_kinematics(imported, written)
    if stem == "hexapod":
        np.testing.assert_allclose(q, _ups_lengths(DATA / "hexapod.toml", poses), atol=1e-9, rtol=0)


def test_hand_written_hexapod_names_its_joints_and_actuators():
    graph = rf.read_sdf(DATA / "hexapod.sdf")
    assert graph.names[0] == "world" and "platform" in graph.names
    # the JointStatePublisher reads leg1_cardan_joint but drives nothing; leg 6 is marked pmaccuracy:actuated
    actuated = sorted(j.name for edge in graph.edges for j in edge if j.actuated)
    assert actuated == [f"joint 'leg{i}_slide'" for i in range(1, 7)]
    balls = [e[0] for e in graph.edges if e[0].kind == "ball"]
    assert len(balls) == 6 and all(b.parent != b.child for b in balls)


def _piston_turned(text: str, how: str, version: str = "1.9") -> str:
    """hexapod.sdf with every piston link turned so that the leg is its z-axis and the slide's axis ``0 0 1`` in
    the joint frame (the child link's), the turn written as roll-pitch-yaw (``how="rpy"``), as SDF 1.9's
    ``quat_xyzw``, in degrees, or (``"parent_model"``, SDF 1.6) the axis kept in the model frame by
    ``use_parent_model_frame``. The turns come from scipy (``from_euler("xyz", [r, p, y])`` is
    ``Rz(y) Ry(p) Rx(r)``, SDF's convention)."""
    for i in range(1, 7):
        m = re.search(rf'<joint name="leg{i}_slide".*?<xyz expressed_in="__model__">([^<]+)</xyz>', text, re.S)
        d = np.array([float(v) for v in m.group(1).split()])
        rot, _ = Rotation.align_vectors([d], [[0.0, 0.0, 1.0]])
        rot = rot * Rotation.from_euler("z", 0.3 * i)            # and some turn about the leg
        if how == "parent_model":
            new_axis = f"<xyz>{m.group(1)}</xyz><use_parent_model_frame>true</use_parent_model_frame>"
        else:
            new_axis = "<xyz>0 0 1</xyz>"
        text = text.replace(m.group(0), m.group(0).replace(f'<xyz expressed_in="__model__">{m.group(1)}</xyz>',
                                                            new_axis))
        old = f'<pose relative_to="leg{i}_cardan">0 0 0 0 0 0</pose>'
        if how == "quat":
            q = rot.as_quat()                                    # x y z w
            new = (f'<pose relative_to="leg{i}_cardan" rotation_format="quat_xyzw">0 0 0 '
                   f'{" ".join(map(str, q.tolist()))}</pose>')
        elif how == "degrees":
            e = rot.as_euler("xyz", degrees=True)
            new = f'<pose relative_to="leg{i}_cardan" degrees="true">0 0 0 {" ".join(map(str, e.tolist()))}</pose>'
        else:
            e = rot.as_euler("xyz")
            new = f'<pose relative_to="leg{i}_cardan">0 0 0 {" ".join(map(str, e.tolist()))}</pose>'
        assert old in text
        text = text.replace(old, new)
    # leg 6's closing ball is in the piston's (now turned) frame: give it in the cardan's instead
    text = text.replace("<child>leg6_piston</child>\n        <pose>", '<child>leg6_piston</child>\n        '
                                                                    '<pose relative_to="leg6_cardan">')
    if version != "1.9":
        text = text.replace('<sdf version="1.9"', f'<sdf version="{version}"')
        text = text.replace(' degrees="true">0 0 0.4 0 0 10<', '>0 0 0.4 0 0 0.17453292519943295<')
        text = text.replace("relative_to=", "frame=")
    return text


@pytest.mark.parametrize("how", ["rpy", "quat", "degrees", "parent_model"])
def test_sdf_pose_conventions_and_axis_frames(how, tmp_path):
    text = (DATA / "hexapod.sdf").read_text()
    version = "1.6" if how == "parent_model" else "1.9"
    path = tmp_path / f"turned_{how}.sdf"
    path.write_text(_piston_turned(text, how, version))
    imported = pm.load_robot(path)
    _same_kinematics(imported, pm.load_robot(DATA / "hexapod.toml"))
    graph = rf.read_sdf(path)
    slides = [j for e in graph.edges for j in e if j.kind == "slide"]
    toml = tomllib.loads((DATA / "hexapod.toml").read_text())
    home = Rotation.from_euler("z", 10, degrees=True)
    for i, (s, leg) in enumerate(zip(slides, toml["legs"])):
        d = np.array([0, 0, 400]) + home.apply(leg["platform"]) - np.array(leg["base"])
        np.testing.assert_allclose(s.axis, d / np.linalg.norm(d), atol=1e-12, rtol=0, err_msg=f"leg {i + 1}")


def test_a_joint_axis_in_the_joint_frame_turns_with_the_joint_pose(tmp_path):
    """A hexapod whose pistons are not turned but whose slide joints are: the joint's own pose (relative to the
    child link) carries the axis ``0 0 1``; SDF 1.6's missing ``use_parent_model_frame`` means the joint frame."""
    text = (DATA / "hexapod.sdf").read_text()
    for i in range(1, 7):
        m = re.search(rf'(<joint name="leg{i}_slide".*?)<xyz expressed_in="__model__">([^<]+)</xyz>', text, re.S)
        d = np.array([float(v) for v in m.group(2).split()])
        rot, _ = Rotation.align_vectors([d], [[0.0, 0.0, 1.0]])
        rpy = " ".join(map(str, rot.as_euler("xyz").tolist()))
        text = text.replace(m.group(0), m.group(1).replace("<axis>", f"<pose>0 0 0 {rpy}</pose>\n        <axis>")
                            + "<xyz>0 0 1</xyz>")
    text = text.replace('<sdf version="1.9"', '<sdf version="1.6"').replace(
        ' degrees="true">0 0 0.4 0 0 10<', '>0 0 0.4 0 0 0.17453292519943295<').replace("relative_to=", "frame=")
    path = tmp_path / "joint_pose.sdf"
    path.write_text(text)
    _same_kinematics(pm.load_robot(path), pm.load_robot(DATA / "hexapod.toml"))


def test_a_model_held_by_nothing_has_its_canonical_link_as_base(tmp_path):
    text = (DATA / "hexapod.sdf").read_text()
    text = re.sub(r'<joint name="fix_base" type="fixed">.*?</joint>', "", text, flags=re.S)
    path = tmp_path / "floating.sdf"
    path.write_text(text)
    _same_kinematics(pm.load_robot(path), pm.load_robot(DATA / "hexapod.toml"))


def _edit(tmp_path, stem, old, new, count=1):
    text = (DATA / f"{stem}.sdf").read_text()
    assert text.count(old) >= 1, old
    path = tmp_path / "bad.sdf"
    path.write_text(text.replace(old, new, count))
    return path


BAD = {
    "not_xml": (lambda t: (t / "junk.sdf", "<sdf version='1.9'><model>\n"), r"junk\.sdf: not a readable XML file"),
    "not_sdf": (lambda t: (t / "robot.sdf", "<robot name='r'/>\n"), r"robot\.sdf: robot: .*root element must be <sdf>"),
    "no_version": (lambda t: (t / "robot.sdf", "<sdf><model name='m'><link name='a'/></model></sdf>\n"),
                   r"robot\.sdf: <sdf>: needs its version attribute"),
    "no_model": (lambda t: (t / "robot.sdf", "<sdf version='1.9'><world name='w'/></sdf>\n"),
                 r"robot\.sdf: <model>: no <model> with joints"),
    "bad_pose": (("hexapod", '<pose relative_to="leg3_mount">0 0 0 0 0 0</pose>',
                  '<pose relative_to="leg3_mount">0 0 0 0 0</pose>'),
                 r"bad\.sdf: link 'leg3_cardan': <pose> expects 6 numbers \(x y z roll pitch yaw\), got '0 0 0 0 0'"),
    "pose_not_numbers": (("delta", "<pose>0 0 1.2 0 0 0</pose>", "<pose>0 0 1,2 0 0 0</pose>"),
                         r"bad\.sdf: link 'frame_link': <pose> expects 6 numbers"),
    "unknown_joint_type": (("hexapod", '<joint name="leg2_slide" type="prismatic">',
                            '<joint name="leg2_slide" type="screw">'),
                           r"bad\.sdf: joint 'leg2_slide': a 'screw' joint cannot be mapped"),
    "missing_link": (("hexapod", "<child>leg4_piston</child>", "<child>leg4_pistn</child>"),
                     r"bad\.sdf: joint 'leg4_slide': its <child> must name a link of the model, got 'leg4_pistn'"),
    "loop_not_closed": (("hexapod", '<joint name="leg5_ball" type="ball">', '<joint name="leg5_ball" type="ball">'
                                                                             '<!--'), None),
    "unknown_frame": (("delta", '<pose relative_to="leg2_mount">0.2 0 0 0 0 0</pose>',
                       '<pose relative_to="leg2_mnt">0.2 0 0 0 0 0</pose>'),
                      r"bad\.sdf: link 'arm2' <pose relative_to='leg2_mnt'>: no link, joint or frame named 'leg2_mnt'"),
    "frame_cycle": (("delta", '<pose relative_to="frame_link">0 0 0 0 0 0</pose></frame>',
                     '<pose relative_to="arm1">0 0 0 0 0 0</pose></frame>'),
                    r"bad\.sdf: (frame 'leg1_mount'|link 'arm1'): its pose is relative to itself through"),
    "driven_unknown_joint": (("delta", "<joint_name>motor2_joint</joint_name>", "<joint_name>motor9</joint_name>"),
                             r"bad\.sdf: <plugin>: drives joint 'motor9', which is not a joint of the model"),
    "missing_actuator": (("delta", "<joint_name>motor2_joint</joint_name>", ""),
                         r"bad\.sdf: joint 'motor2_joint': a delta leg needs its actuated joint"),
    "bad_limit": (("delta", "<lower>-0.6981317007977318</lower>", "<lower>2</lower>"),
                  r"bad\.sdf: joint 'motor1_joint' <axis><limit>: expects numbers <lower> <= <upper>"),
    "zero_axis": (("delta", "<xyz>0 1 0</xyz>", "<xyz>0 0 0</xyz>"),
                  r"bad\.sdf: joint 'motor1_joint' <axis><xyz>: expected three numbers of a non-zero vector"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_sdf_files_are_refused_in_one_line(case, tmp_path, capsys):
    make, pattern = BAD[case]
    if callable(make):
        path, text = make(tmp_path)
        path.write_text(text)
    else:
        stem, old, new = make
        if case == "loop_not_closed":      # comment out leg 5's closing ball joint
            text = (DATA / "hexapod.sdf").read_text()
            i = text.index('<joint name="leg5_ball" type="ball">')
            j = text.index("</joint>", i) + len("</joint>")
            path = tmp_path / "bad.sdf"
            path.write_text(text[:i] + "<!-- " + text[i:j] + " -->" + text[j:])
            pattern = (r"bad\.sdf: joint 'leg5_slide': a chain from the base ends at 'leg5_piston' without closing "
                       r"a loop to the platform 'platform'")
        else:
            path = _edit(tmp_path, stem, old, new)
    status, out, err = run_cli(["import", path], capsys)
    assert status == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pmaccuracy import: error: "), err
    assert re.search(pattern, lines[0]), lines[0]


def test_import_and_export_commands_read_and_write_sdf(tmp_path, capsys):
    out = tmp_path / "hexapod.toml"
    status, stdout, err = run_cli(["import", DATA / "hexapod.sdf", "--out", out], capsys)
    assert status == 0, err
    assert "6-UPS" in stdout and "leg 6:" in stdout
    assert_same_robot(pm.load_robot(DATA / "hexapod.sdf"), pm.load_robot(out))
    status, stdout, err = run_cli(["ik", "--robot", DATA / "hexapod.sdf", "--pose", 0, 0, 400, 0, 0, 10], capsys)
    assert status == 0, err
    status, _, err = run_cli(["export", "rps_3", "--to", tmp_path / "r.sdf"], capsys)
    assert status == 0, err
    assert_same_robot(pm.load_robot("rps_3"), pm.load_robot(tmp_path / "r.sdf"))
    status, _, err = run_cli(["export", "symmetric_3rrr", "--to", tmp_path / "p.sdf"], capsys)
    assert status == 2 and "planar robot" in err


def _calibrated(robot, seed):
    """The robot with every base and platform point (and a Delta's arms and rods) moved by about 0.5 mm and the
    home pose moved (turned only for a robot whose platform turns)."""
    rng = np.random.default_rng(seed)
    legs = []
    for leg in robot.legs:
        change = dict(base=tuple(np.add(leg.base, rng.normal(0, 0.5, 3))),
                      platform=tuple(np.add(leg.platform, rng.normal(0, 0.5, 3))))
        for key in ("rod", "arm"):
            if hasattr(leg, key):
                change[key] = getattr(leg, key) + rng.normal(0, 0.3)
        legs.append(dataclasses.replace(leg, **change))
    turn = [0.001, 0.002, -0.001] if robot.mobility != "3T" else [0.0, 0.0, 0.0]
    return dataclasses.replace(robot, legs=tuple(legs), home=tuple(np.add(robot.home, [0.3, -0.2, 1.0] + turn)))


def _structure(path):
    """Every element of the file but the geometry: (tag, attributes, text), the geometry's texts left out."""
    geometry = {"pose", "xyz", "lower", "upper", f"{{{rf.SDF_NAMESPACE}}}extras"}
    out = []
    for el in ET.parse(path).getroot().iter():
        attrs = {k: v for k, v in el.attrib.items() if not (el.tag == "pose" and k in ("degrees", "rotation_format"))}
        out.append((el.tag, attrs, None if el.tag in geometry else (el.text or "").strip()))
    return [e for e in out if e[0] != f"{{{rf.SDF_NAMESPACE}}}extras"]


@pytest.mark.parametrize("stem", ["hexapod", "delta"])
def test_calibrated_robot_written_into_its_sdf_changes_only_the_geometry(stem, tmp_path):
    robot = pm.load_robot(DATA / f"{stem}.sdf")
    cal = _calibrated(robot, seed=5)
    out = pm.export_robot(cal, tmp_path / f"{stem}_calibrated.sdf", like=DATA / f"{stem}.sdf")
    assert_same_robot(cal, pm.load_robot(out))
    assert _structure(out) == _structure(DATA / f"{stem}.sdf")
    original, written = (DATA / f"{stem}.sdf").read_text(), out.read_text()
    assert written[:written.index("<sdf")] == original[:original.index("<sdf")]     # the comments before <sdf>


def test_calibrated_hexapod_joints_are_at_the_calibrated_points(tmp_path):
    """The written file's joints, placed by the reference frame rules (tests/reference), are the calibrated
    robot's base points, platform points at the home pose (scipy) and leg directions, in the base link's frame."""
    cal = _calibrated(pm.load_robot(DATA / "hexapod.sdf"), seed=7)
    out = pm.export_robot(cal, tmp_path / "hexapod_calibrated.sdf", like=DATA / "hexapod.sdf")
    model = sdf_frames_reference.model_of(out)
    pb, Rb = sdf_frames_reference.pose_in_model(model, "base")
    home_p, home_R = np.asarray(cal.home[:3]), Rotation.from_rotvec(cal.home[3:])
    for i, leg in enumerate(cal.legs, start=1):
        A = np.asarray(leg.base)
        B = home_p + home_R.apply(leg.platform)
        a = Rb.inv().apply(sdf_frames_reference.pose_in_model(model, f"leg{i}_cardan_joint")[0] - pb) * 1000
        b = Rb.inv().apply(sdf_frames_reference.pose_in_model(model, f"leg{i}_ball")[0] - pb) * 1000
        np.testing.assert_allclose(a, A, atol=1e-9, rtol=0)
        np.testing.assert_allclose(b, B, atol=1e-9, rtol=0)
        slide = next(j for j in model.findall("joint") if j.get("name") == f"leg{i}_slide")
        d = Rb.inv().apply([float(v) for v in slide.findtext("axis/xyz").split()])
        np.testing.assert_allclose(d, (B - A) / np.linalg.norm(B - A), atol=1e-12, rtol=0)


def test_reference_frames_agree_with_the_hand_written_hexapod():
    """The reference rules themselves, on the hand-written file: the closing balls at the TOML's points."""
    model = sdf_frames_reference.model_of(DATA / "hexapod.sdf")
    toml = tomllib.loads((DATA / "hexapod.toml").read_text())
    home = Rotation.from_euler("z", 10, degrees=True)
    pb, _ = sdf_frames_reference.pose_in_model(model, "base")
    for i, leg in enumerate(toml["legs"], start=1):
        b = (sdf_frames_reference.pose_in_model(model, f"leg{i}_ball")[0] - pb) * 1000
        np.testing.assert_allclose(b, np.array([0, 0, 400]) + home.apply(leg["platform"]), atol=1e-9, rtol=0)


def test_export_command_writes_a_calibrated_robot_into_its_sdf(tmp_path, capsys):
    cal = _calibrated(pm.load_robot(DATA / "delta.sdf"), seed=9)
    toml = tmp_path / "cal.toml"
    cal.to_toml(toml)
    status, stdout, err = run_cli(["export", toml, "--to", tmp_path / "cal.sdf", "--like", DATA / "delta.sdf"], capsys)
    assert status == 0, err
    assert_same_robot(pm.load_robot(toml), pm.load_robot(tmp_path / "cal.sdf"))
    status, _, err = run_cli(["export", toml, "--to", tmp_path / "cal.xml", "--like", DATA / "delta.sdf"], capsys)
    assert status == 2 and "--to" in err and ".sdf" in err


@pytest.mark.parametrize("name", PRESETS)
def test_calibrated_preset_written_into_its_exported_sdf_reads_back(name, tmp_path):
    robot = SpatialManipulator.preset(name)
    original = rf.write_sdf(robot, tmp_path / "original.sdf")
    cal = _calibrated(robot, seed=13)
    assert_same_robot(cal, pm.load_robot(rf.export_into(cal, original, tmp_path / "calibrated.sdf")))


def test_a_joint_may_name_a_frame_attached_to_a_link(tmp_path):
    text = (DATA / "hexapod.sdf").read_text()
    old = "<parent>base</parent>\n        <child>leg2_cardan</child>"
    assert old in text
    path = tmp_path / "frame_parent.sdf"
    path.write_text(text.replace(old, "<parent>base_plate</parent>\n        <child>leg2_cardan</child>"))
    _same_kinematics(pm.load_robot(path), pm.load_robot(DATA / "hexapod.toml"))


def test_sdf_1_6_joints_may_share_their_link_names(tmp_path):
    """SDF 1.6 allowed a joint and a link of one name (converters from URDF write them): both are read, and a
    calibrated robot is written back into such a file."""
    text = (DATA / "hexapod.sdf").read_text()
    text = text.replace('<sdf version="1.9"', '<sdf version="1.6"').replace(
        ' degrees="true">0 0 0.4 0 0 10<', '>0 0 0.4 0 0 0.17453292519943295<').replace("relative_to=", "frame=")
    for i in range(1, 7):
        text = text.replace(f'<joint name="leg{i}_slide"', f'<joint name="leg{i}_piston"')
        text = text.replace(f"<joint_name>leg{i}_slide</joint_name>", f"<joint_name>leg{i}_piston</joint_name>")
    path = tmp_path / "shared.sdf"
    path.write_text(text)
    imported = pm.load_robot(path)
    _same_kinematics(imported, pm.load_robot(DATA / "hexapod.toml"))
    slides = [j.name for e in rf.read_sdf(path).edges for j in e if j.kind == "slide" and j.actuated]
    assert slides == [f"joint 'leg{i}_piston'" for i in range(1, 7)]
    cal = _calibrated(imported, seed=21)
    assert_same_robot(cal, pm.load_robot(pm.export_robot(cal, tmp_path / "shared_cal.sdf", like=path)))

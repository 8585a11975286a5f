"""Robots from and to MJCF and URDF files (``pmaccuracy.io.robot_formats``).

The files of ``tests/data/formats`` were written by hand in the shapes CAD exporters write (numbers from a
calculator, not from our writer), each beside the hand-written TOML of the same robot. Checked here:

* every spatial preset written as MJCF and as URDF and read back is the same robot (every leg key to 1e-9, the
  same inverse kinematics at random poses to 1e-9);
* each hand-written file imports to its TOML's kinematics (1e-9), and the hexapod's leg lengths equal the closed
  form ``|p + R b - A|`` computed here with scipy's rotations from the TOML numbers;
* a calibrated robot written into the original MJCF and reloaded by MuJoCo has MuJoCo's world anchors at the
  calibrated geometry (1e-12 m), computed here from the calibrated numbers;
* bad files end the CLI with status 2 and one line naming the file and the element.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli
from scipy.spatial.transform import Rotation

import pmaccuracy as pm
from robot_compare import assert_same_robot, random_poses
from pmaccuracy.kinematics.spatial import inverse_kinematics
from pmaccuracy.model.spatial import SpatialManipulator

mujoco = pytest.importorskip("mujoco")
rf = pytest.importorskip("pmaccuracy.io.robot_formats")

DATA = Path(__file__).parents[1] / "data" / "formats"
PRESETS = SpatialManipulator.preset_names()


@pytest.mark.parametrize("name", PRESETS)
@pytest.mark.parametrize("suffix", [".xml", ".urdf"])
def test_every_spatial_preset_survives_a_round_trip(name, suffix, tmp_path):
    if suffix == ".urdf":
        pytest.importorskip("yourdfpy")
    robot = SpatialManipulator.preset(name)
    path = tmp_path / f"{name}{suffix}"
    (rf.write_mjcf if suffix == ".xml" else rf.write_urdf)(robot, path)
    back = pm.load_robot(path)
    assert_same_robot(robot, back)
    assert back.name == robot.name and back.description == robot.description


def _ups_lengths(toml_path, poses):
    """Leg lengths |p + R b - A| from the TOML numbers (scipy's rotation of the rotation vector)."""
    import tomllib

    data = tomllib.loads(Path(toml_path).read_text())
    A = np.array([leg["base"] for leg in data["legs"]])
    b = np.array([leg["platform"] for leg in data["legs"]])
    R = Rotation.from_rotvec(poses[:, 3:]).as_matrix()
    B = poses[:, None, :3] + np.einsum("nij,lj->nli", R, b)
    return np.linalg.norm(B - A, axis=-1)


@pytest.mark.parametrize("stem", ["hexapod", "hexapod_hanging", "delta", "tilt_head"])
def test_hand_written_files_import_to_their_hand_written_toml(stem):
    suffix = ".urdf" if stem == "tilt_head" else ".xml"
    if suffix == ".urdf":
        pytest.importorskip("yourdfpy")
    imported = pm.load_robot(DATA / f"{stem}{suffix}")
    stem = stem.replace("_hanging", "")        # leg 6 written from the platform to the base: the same robot
    written = pm.load_robot(DATA / f"{stem}.toml")
    assert imported.architecture == written.architecture
    np.testing.assert_allclose(imported.home, written.home, atol=1e-9, rtol=0)
    for la, lb in zip(imported.legs, written.legs):
        np.testing.assert_allclose(la.base, lb.base, atol=1e-9, rtol=0)
        np.testing.assert_allclose(la.platform, lb.platform, atol=1e-9, rtol=0)
        np.testing.assert_allclose(la.stroke, lb.stroke, atol=1e-9, rtol=0)
    poses = random_poses(written, seed=3)
    q = inverse_kinematics(imported, poses).q
    np.testing.assert_allclose(q, inverse_kinematics(written, poses).q, atol=1e-9, rtol=0)
    if stem != "delta":
        np.testing.assert_allclose(q, _ups_lengths(DATA / f"{stem}.toml", poses), atol=1e-9, rtol=0)


def _with_sites(tmp_path):
    """hexapod.xml with leg 6 closed by a site-based connect (as onshape-to-robot writes its closing frames)."""
    text = (DATA / "hexapod.xml").read_text()
    old = '<connect name="leg6_ball" body1="platform" body2="leg6_piston" anchor="0.051303021499 -0.140953893118 0"/>'
    assert old in text
    text = text.replace(old, '<connect name="leg6_ball" site1="plat6" site2="tip6"/>')
    text = text.replace('<geom type="cylinder" size="0.17 0.01" rgba="0.8 0.5 0.2 1"/>',
                        '<geom type="cylinder" size="0.17 0.01" rgba="0.8 0.5 0.2 1"/>\n'
                        '      <site name="plat6" pos="0.051303021499 -0.140953893118 0"/>')
    i = text.index('<body name="leg6_piston">')
    j = text.index("</body>", i)
    text = text[:j] + '  <site name="tip6" pos="0 0 0.4633024013842581"/>\n        ' + text[j:]
    path = tmp_path / "sites.xml"
    path.write_text(text)
    return path


def test_site_based_connects_close_loops_and_move_with_the_calibration(tmp_path):
    path = _with_sites(tmp_path)
    assert_same_robot(pm.load_robot(DATA / "hexapod.xml"), pm.load_robot(path))
    cal = _calibrated(pm.load_robot(path), seed=9)
    out = rf.export_into(cal, path, tmp_path / "sites_calibrated.xml")
    m = mujoco.MjModel.from_xml_path(str(out))
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    B = np.array([0.0, 0.0, 0.05]) + np.asarray(cal.home[:3]) / 1000 + \
        Rotation.from_rotvec(cal.home[3:]).as_matrix() @ np.asarray(cal.legs[5].platform) / 1000
    for site in ("plat6", "tip6"):
        np.testing.assert_allclose(d.site_xpos[m.site(site).id], B, atol=1e-12)
    assert_same_robot(cal, pm.load_robot(out))


def test_a_free_root_body_is_the_base(tmp_path):
    """Exporters give the robot's root body a free joint by default: with nothing else holding to the world it is
    the base (the Delta's fixed frame body made free: the same robot)."""
    path = _edit(tmp_path, "delta", '<body name="frame" pos="0 0 1.2">',
                 '<body name="frame" pos="0 0 1.2">\n      <freejoint name="floating_base"/>')
    assert_same_robot(pm.load_robot(DATA / "delta.toml"), pm.load_robot(path))


def test_delta_arm_angles_close_the_rods_of_the_hand_written_file():
    """The imported Delta's arm angles put each elbow ball one rod length from its platform ball, with the ball
    positions computed here from the MJCF's numbers (arm 0.35 m along x of each arm frame, balls +-0.05 m)."""
    robot = pm.load_robot(DATA / "delta.xml")
    poses = random_poses(robot, seed=5)
    q = inverse_kinematics(robot, poses).q
    for i in range(3):
        c, s = np.cos(np.radians(120 * i)), np.sin(np.radians(120 * i))
        Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
        A = Rz @ [200.0, 0, 0]
        for side in (1, -1):
            # arm frame: x along the arm at 0, hinge axis y; a positive angle turns x towards -z (right hand about y)
            elbow = A[None] + (Rz @ np.stack([350 * np.cos(q[:, i]), np.full(len(q), 50.0 * side),
                                              -350 * np.sin(q[:, i])])).T
            ball = poses[:, :3] + Rz @ [50.0, 50.0 * side, 0]
            np.testing.assert_allclose(np.linalg.norm(ball - elbow, axis=1), 800.0, atol=1e-9)


def _calibrated(robot, seed=2):
    rng = np.random.default_rng(seed)
    legs = []
    for leg in robot.legs:
        change = dict(base=tuple(np.asarray(leg.base) + rng.normal(0, 0.4, 3)),
                      platform=tuple(np.asarray(leg.platform) + rng.normal(0, 0.4, 3)))
        if hasattr(leg, "rod"):
            change["rod"] = leg.rod + rng.normal(0, 0.3)
        if hasattr(leg, "arm"):
            change["arm"] = leg.arm + rng.normal(0, 0.3)
        legs.append(dataclasses.replace(leg, **change))
    home = np.asarray(robot.home) + np.r_[rng.normal(0, 0.5, 3), 0, 0, 0]
    return dataclasses.replace(robot, legs=tuple(legs), home=tuple(home))


def _world(m, d, body, local_m):
    return d.xpos[body] + d.xmat[body].reshape(3, 3) @ local_m


def test_calibrated_hexapod_written_into_a_leg_hanging_from_the_platform(tmp_path):
    original = DATA / "hexapod_hanging.xml"
    cal = _calibrated(pm.load_robot(original), seed=4)
    out = rf.export_into(cal, original, tmp_path / "hanging_calibrated.xml")
    m = mujoco.MjModel.from_xml_path(str(out))
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    A = np.array([0.0, 0.0, 0.05]) + np.asarray(cal.legs[5].base) / 1000
    B = np.array([0.0, 0.0, 0.05]) + np.asarray(cal.home[:3]) / 1000 + \
        Rotation.from_rotvec(cal.home[3:]).as_matrix() @ np.asarray(cal.legs[5].platform) / 1000
    np.testing.assert_allclose(d.xanchor[m.joint("leg6_sphere").id], B, atol=1e-12)
    np.testing.assert_allclose(d.xanchor[m.joint("leg6_u1").id], A, atol=1e-12)
    # the slide's axis in the file still points from the ball towards the base joint
    np.testing.assert_allclose(d.xaxis[m.joint("leg6_slide").id], (A - B) / np.linalg.norm(A - B), atol=1e-12)
    assert_same_robot(cal, pm.load_robot(out))


def test_calibrated_hexapod_written_into_its_mjcf_is_mujocos_geometry(tmp_path):
    original = DATA / "hexapod.xml"
    cal = _calibrated(pm.load_robot(original))
    out = rf.export_into(cal, original, tmp_path / "hexapod_calibrated.xml")
    m = mujoco.MjModel.from_xml_path(str(out))
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    base = np.array([0.0, 0.0, 0.05])                      # the file's fixed base body
    p = np.asarray(cal.home[:3]) / 1000 + base
    R = Rotation.from_rotvec(cal.home[3:]).as_matrix()
    for i, leg in enumerate(cal.legs, start=1):
        A = base + np.asarray(leg.base) / 1000
        B = p + R @ np.asarray(leg.platform) / 1000
        for name in (f"leg{i}_u1", f"leg{i}_u2"):
            np.testing.assert_allclose(d.xanchor[m.joint(name).id], A, atol=1e-12)
        slide = m.joint(f"leg{i}_slide").id
        np.testing.assert_allclose(np.cross(d.xaxis[slide], (B - A) / np.linalg.norm(B - A)), 0, atol=1e-12)
        eq = m.equality(f"leg{i}_ball").id
        np.testing.assert_allclose(_world(m, d, m.eq_obj1id[eq], m.eq_data[eq, :3]), B, atol=1e-12)
        np.testing.assert_allclose(d.xpos[m.body("platform").id], p, atol=1e-12)
    text = out.read_text()
    for kept in ('kp="2000"', 'rgba="0.8 0.5 0.2 1"', 'timestep="0.002"', 'name="floor"'):
        assert kept in text
    assert_same_robot(cal, pm.load_robot(out))


def test_calibrated_delta_written_into_its_mjcf_closes_its_rods(tmp_path):
    original = DATA / "delta.xml"
    cal = _calibrated(pm.load_robot(original))
    out = rf.export_into(cal, original, tmp_path / "delta_calibrated.xml")
    m = mujoco.MjModel.from_xml_path(str(out))
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    frame = np.array([0.0, 0.0, 1.2])
    p = frame + np.asarray(cal.home[:3]) / 1000
    for i, leg in enumerate(cal.legs, start=1):
        motor = m.joint(f"motor{i}_joint").id
        np.testing.assert_allclose(d.xanchor[motor], frame + np.asarray(leg.base) / 1000, atol=1e-12)
        np.testing.assert_allclose(d.xaxis[motor], leg.axis, atol=1e-12)
        elbows = [d.xanchor[m.joint(f"elbow{i}{s}").id] for s in "ab"]
        mid = 0.5 * (elbows[0] + elbows[1])
        arm = mid - d.xanchor[motor]
        assert abs(arm @ np.asarray(leg.axis)) < 1e-12
        assert np.linalg.norm(arm) == pytest.approx(leg.arm / 1000, abs=1e-12)
        assert np.linalg.norm(elbows[0] - elbows[1]) == pytest.approx(leg.spacing / 1000, abs=1e-12)
        for elbow in elbows:
            sign = 1 if (elbow - mid) @ np.asarray(leg.axis) > 0 else -1
            ball = p + (np.asarray(leg.platform) + sign * 0.5 * leg.spacing * np.asarray(leg.axis)) / 1000
            assert np.linalg.norm(ball - elbow) == pytest.approx(leg.rod / 1000, abs=1e-12)
    assert_same_robot(cal, pm.load_robot(out))


@pytest.mark.parametrize("name", PRESETS)
def test_calibrated_preset_written_into_its_exported_mjcf_reads_back(name, tmp_path):
    robot = SpatialManipulator.preset(name)
    original = rf.write_mjcf(robot, tmp_path / "original.xml")
    cal = _calibrated(robot, seed=7)
    assert_same_robot(cal, pm.load_robot(rf.export_into(cal, original, tmp_path / "calibrated.xml")))


# ---------------------------------------------------------------------------------------------- bad files
def _edit(tmp_path, stem, old, new, suffix=".xml"):
    text = (DATA / f"{stem}{suffix}").read_text()
    assert old in text
    path = tmp_path / f"bad{suffix}"
    path.write_text(text.replace(old, new, 1))
    return path


BAD = {
    "not_xml": (lambda t: (t / "junk.xml", "this is not XML\n"), r"junk\.xml: MuJoCo cannot read it"),
    "urdf_not_xml": (lambda t: (t / "junk.urdf", "<robot><link name='a'>\n"), r"junk\.urdf: not a readable XML file"),
    "unknown_joint": (("hexapod", '<joint name="leg2_u1" axis="1 0 0"/>', '<joint name="leg2_u1" type="hing"/>'),
                      r"bad\.xml: MuJoCo cannot read it: .*invalid keyword: 'hing'"),
    "missing_actuator": (("hexapod", '<position name="leg3_motor" joint="leg3_slide" kp="2000" ctrlrange="-0.09 0.09"/>',
                          ""), r"bad\.xml: joint 'leg3_slide': a 6-UPS leg needs its actuated joint .*leg 3 has none"),
    "actuator_elsewhere": (("hexapod", 'joint="leg3_slide" kp', 'joint="leg3_u1" kp'),
                           r"bad\.xml: joint 'leg3_slide': .*leg 3 has joint 'leg3_u1' instead"),
    "loop_not_closed": (("hexapod", '<connect name="leg4_ball" body1="platform" body2="leg4_piston" '
                                    'anchor="-0.147721162952 0.02604722665 0"/>', ""),
                        r"bad\.xml: joint 'leg4_slide': a chain from the base ends at 'leg4_piston' without closing"),
    "rods_not_parallel": (("delta", 'anchor="0.01830127018922193 0.06830127018922193 0"',
                           'anchor="0.01830127018922193 0.07830127018922193 0"'),
                          r"bad\.xml: .*leg 2: the two rods must be equal and parallel"),
    "urdf_unknown_link": (("tilt_head", '<child link="leg2_rod"/>', '<child link="leg2_rodd"/>', ".urdf"),
                          r"bad\.urdf: joint 'leg2_piston': its <child link=...> must name a link of the robot, "
                          r"got 'leg2_rodd'"),
    "urdf_loop_open": (("tilt_head", '<origin xyz="0 0 0.36400549446402586" rpy="0 0 0"/></predecessor>\n'
                                     '    <successor name="platform"><origin xyz="0 0.1 0"',
                        '<origin xyz="0 0 0.36400549446402586" rpy="0 0 0"/></predecessor>\n'
                        '    <successor name="platform"><origin xyz="0 0.12 0"', ".urdf"),
                       r"bad\.urdf: loop 'leg1_ball': its two ends are 20 mm apart .*not closed"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_files_are_refused_in_one_line(case, tmp_path, capsys):
    make, pattern = BAD[case]
    if callable(make):
        path, text = make(tmp_path)
        path.write_text(text)
    else:
        if len(make) == 4:
            pytest.importorskip("yourdfpy")
        path = _edit(tmp_path, *make)
    status, out, err = run_cli(["import", path], capsys)
    assert status == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pmaccuracy import: error: "), err
    assert re.search(pattern, lines[0]), lines[0]


def test_import_writes_a_toml_every_command_reads(tmp_path, capsys):
    out = tmp_path / "hexapod.toml"
    status, stdout, err = run_cli(["import", DATA / "hexapod.xml", "--out", out], capsys)
    assert status == 0, err
    assert "6-UPS" in stdout and "leg 6:" in stdout
    assert_same_robot(pm.load_robot(DATA / "hexapod.xml"), pm.load_robot(out))
    status, stdout, err = run_cli(["ik", "--robot", DATA / "hexapod.xml", "--pose", 0, 0, 400, 0, 0, 10], capsys)
    assert status == 0, err


def test_export_command_writes_fresh_files_and_into_the_original(tmp_path, capsys):
    status, _, err = run_cli(["export", "delta_clavel", "--to", tmp_path / "d.xml"], capsys)
    assert status == 0, err
    assert_same_robot(pm.load_robot("delta_clavel"), pm.load_robot(tmp_path / "d.xml"))
    toml = tmp_path / "cal.toml"
    cal = _calibrated(pm.load_robot(DATA / "hexapod.xml"))
    cal.to_toml(toml)
    status, _, err = run_cli(["export", toml, "--to", tmp_path / "h.xml", "--like", DATA / "hexapod.xml"], capsys)
    assert status == 0, err
    assert_same_robot(cal, pm.load_robot(tmp_path / "h.xml"))
    status, _, err = run_cli(["export", "rps_3", "--to", tmp_path / "h2.xml", "--like", DATA / "hexapod.xml"], capsys)
    assert status == 2 and "holds a 6-UPS with 6 legs, the robot is a 3-RPS" in err


# ---------------------------------------------------------------------------------------------- planar robots
PLANAR = ["aalborg_3ppr", "symmetric_3rrr", "symmetric_3rpr", "symmetric_3prr", "symmetric_3ppr"]


def _planarrandom_poses(n=25, seed=0):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-10, 10, n), rng.uniform(-10, 10, n), rng.uniform(-0.1, 0.1, n)])


def _same_planar(a, b):
    from pmaccuracy.kinematics import inverse_kinematics as planar_ik

    poses = _planarrandom_poses()
    qa, qb = planar_ik(a, poses).q, planar_ik(b, poses).q
    assert np.all(np.isfinite(qa))
    np.testing.assert_allclose(qb, qa, atol=1e-9, rtol=0)
    for ca, cb in zip(a.chains, b.chains):
        assert ca.pattern == cb.pattern and ca.actuated_index == cb.actuated_index
        np.testing.assert_allclose(cb.actuated.range, ca.actuated.range, atol=1e-9, rtol=0)
        # the platform point of the leg's last joint, in the platform frame
        np.testing.assert_allclose(complex(cb.platform_z), complex(ca.platform_z), atol=1e-9)


@pytest.mark.parametrize("name", PLANAR)
def test_every_planar_preset_survives_an_mjcf_round_trip(name, tmp_path):
    robot = pm.load_robot(name)
    back = pm.load_robot(rf.write_mjcf(robot, tmp_path / f"{name}.xml"))
    assert back.name == robot.name and back.architecture == "chain"
    _same_planar(robot, back)


def test_hand_written_planar_mjcf_is_the_symmetric_3rrr():
    """planar_3rrr.xml: elbows placed by hand (isosceles triangles of 120 mm links over the 150 mm base-platform
    distance, on the right of A -> B, the TOML's working mode +1)."""
    _same_planar(pm.load_robot("symmetric_3rrr"), pm.load_robot(DATA / "planar_3rrr.xml"))


def test_calibrated_tilt_head_written_into_its_urdf_is_yourdfpys_geometry(tmp_path):
    """The calibrated 3-RPS written into tilt_head.urdf: yourdfpy's link frames put each revolute at the
    calibrated base point and each loop's two ends at the calibrated platform point (1e-12 m)."""
    yourdfpy = pytest.importorskip("yourdfpy")
    import xml.etree.ElementTree as ET

    original = DATA / "tilt_head.urdf"
    cal = _calibrated(pm.load_robot(original), seed=11)
    out = rf.export_into(cal, original, tmp_path / "tilt_calibrated.urdf")
    urdf = yourdfpy.URDF.load(str(out), build_scene_graph=True, load_meshes=False, build_collision_scene_graph=False)
    R = Rotation.from_rotvec(cal.home[3:]).as_matrix()
    loops = {el.get("name"): el for el in ET.parse(out).getroot().iter("loop")}
    for i, leg in enumerate(cal.legs, start=1):
        T = urdf.get_transform(f"leg{i}_cylinder", "base_link")
        np.testing.assert_allclose(T[:3, 3], np.asarray(leg.base) / 1000, atol=1e-12)
        np.testing.assert_allclose(T[:3, :3] @ [1.0, 0.0, 0.0], leg.axis, atol=1e-12)   # the file's local axis
        B = (np.asarray(cal.home[:3]) + R @ np.asarray(leg.platform)) / 1000
        loop = loops[f"leg{i}_ball"]
        for end in ("predecessor", "successor"):
            link = loop.find(end).get("name")
            xyz = np.array([float(v) for v in loop.find(end).find("origin").get("xyz").split()])
            T = urdf.get_transform(link, "base_link")
            np.testing.assert_allclose(T[:3, 3] + T[:3, :3] @ xyz, B, atol=1e-12)
    text = out.read_text()
    assert "transmission_interface/SimpleTransmission" in text and 'radius="0.22"' in text
    assert_same_robot(cal, pm.load_robot(out))


@pytest.mark.parametrize("name", PRESETS)
def test_calibrated_preset_written_into_its_exported_urdf_reads_back(name, tmp_path):
    pytest.importorskip("yourdfpy")
    robot = SpatialManipulator.preset(name)
    original = rf.write_urdf(robot, tmp_path / "original.urdf")
    cal = _calibrated(robot, seed=13)
    assert_same_robot(cal, pm.load_robot(rf.export_into(cal, original, tmp_path / "calibrated.urdf")))


@pytest.mark.parametrize("axis", ["0 -1 0", "0 1 0"])
def test_a_planar_robot_drawn_in_the_xz_plane_has_plane_coordinates_x_z(axis, tmp_path):
    """planar_3rrr.xml redrawn upright: every point (u, v, 0) to (u, 0, v), the hinges about -y (or +y, the joint
    values then turning the other way): the same robot with plane coordinates (x, z)."""
    text = (DATA / "planar_3rrr.xml").read_text()
    sign = -1.0 if axis == "0 -1 0" else 1.0

    def upright(match):
        values = [float(v) for v in match.group(2).split()]
        out = []
        for k in range(0, len(values), 3):
            u, v, w = values[k:k + 3]
            out += [u, -w, v]
        return f'{match.group(1)}="{" ".join(repr(x) for x in out)}"'

    text = re.sub(r'(pos|fromto|anchor)="([^"]*)"', upright, text).replace('axis="0 0 1"', f'axis="{axis}"')
    if sign > 0:   # the motors' reference angles and ranges turn the other way
        text = re.sub(r'ref="([^"]*)" range="([^"]*) ([^"]*)"',
                      lambda m: f'ref="{-float(m.group(1))!r}" range="{-float(m.group(3))!r} {-float(m.group(2))!r}"',
                      text)
    path = tmp_path / "upright.xml"
    path.write_text(text)
    upright_robot = pm.load_robot(path)
    if sign < 0:
        _same_planar(pm.load_robot("symmetric_3rrr"), upright_robot)
    else:   # the same mechanism: the same actuated angles up to the sign of each motor's axis
        from pmaccuracy.kinematics import inverse_kinematics as planar_ik

        poses = _planarrandom_poses()
        qa = planar_ik(pm.load_robot("symmetric_3rrr"), poses).q
        qb = planar_ik(upright_robot, poses).q
        np.testing.assert_allclose(np.cos(qb), np.cos(qa), atol=1e-9)
        np.testing.assert_allclose(np.sin(qb), np.sin(qa), atol=1e-9)


@pytest.mark.parametrize("stem", ["hexapod", "delta"])
def test_files_typed_to_ten_micrometres_import_within_their_typing_error(stem, tmp_path):
    """Every decimal number of the hand-written file rounded to 1e-5 (m, deg): still the same legs, with
    kinematics within the rounding (5 um per number: under 0.05 mm of leg length, 1e-4 rad of arm angle)."""
    text = re.sub(r"-?\d+\.\d+", lambda m: f"{float(m.group()):.5f}", (DATA / f"{stem}.xml").read_text())
    path = tmp_path / f"{stem}.xml"
    path.write_text(text)
    typed, exact = pm.load_robot(path), pm.load_robot(DATA / f"{stem}.toml")
    poses = random_poses(exact, seed=21)
    err = np.abs(inverse_kinematics(typed, poses).q - inverse_kinematics(exact, poses).q)
    assert np.max(err) < (0.05 if stem == "hexapod" else 1e-4)


def _gazebo_loops(tmp_path):
    """tilt_head.urdf with each URDF+ loop replaced by Gazebo's closure: an SDFormat ball joint in a <gazebo>
    extension, posed in the child link (the platform) at the platform ball."""
    def joint(m):
        return (f'<gazebo>\n    <joint name="{m.group(1)}" type="ball">\n      <parent>{m.group(2)}</parent>\n'
                f'      <child>platform</child>\n      <pose>{m.group(3)} 0 0 0</pose>\n    </joint>\n  </gazebo>')

    text = re.sub(r'<loop name="([^"]+)" type="spherical">\s*<predecessor name="([^"]+)"><origin xyz="[^"]*" '
                  r'rpy="0 0 0"/></predecessor>\s*<successor name="platform"><origin xyz="([^"]*)" rpy="0 0 0"/>'
                  r'</successor>\s*</loop>', joint, (DATA / "tilt_head.urdf").read_text())
    assert text.count("<gazebo>") == 3 and "<loop name" not in text
    path = tmp_path / "tilt_gazebo.urdf"
    path.write_text(text)
    return path


def test_gazebo_joints_close_urdf_loops(tmp_path):
    pytest.importorskip("yourdfpy")
    path = _gazebo_loops(tmp_path)
    assert_same_robot(pm.load_robot(DATA / "tilt_head.urdf"), pm.load_robot(path))
    cal = _calibrated(pm.load_robot(path), seed=17)
    assert_same_robot(cal, pm.load_robot(rf.export_into(cal, path, tmp_path / "tilt_gazebo_calibrated.urdf")))


def test_import_of_a_planar_file_prints_its_chains_and_writes_a_toml(tmp_path, capsys):
    out = tmp_path / "p.toml"
    status, stdout, err = run_cli(["import", DATA / "planar_3rrr.xml", "--out", out], capsys)
    assert status == 0, err
    assert "leg 1: RRR, base [-173.205, -100] mm, platform [-43.3013, -25] mm, actuated joint 1 range [-110, 70] deg" \
        in stdout
    _same_planar(pm.load_robot("symmetric_3rrr"), pm.load_robot(out))


def test_onshape_closing_frames_close_urdf_loops(tmp_path):
    """tilt_head.urdf with each loop written as onshape-to-robot's pair of frames closing_NAME_1 (on the piston)
    and closing_NAME_2 (on the platform), fixed links meeting at the ball."""
    pytest.importorskip("yourdfpy")

    def frames(m):
        name, pred, pxyz, sxyz = m.groups()
        return (f'<link name="closing_{name}_1"/>\n  <joint name="{name}_frame_1" type="fixed"><parent link="{pred}"/>'
                f'<child link="closing_{name}_1"/><origin xyz="{pxyz}" rpy="0 0 0"/></joint>\n'
                f'  <link name="closing_{name}_2"/>\n  <joint name="{name}_frame_2" type="fixed"><parent link="platform"/>'
                f'<child link="closing_{name}_2"/><origin xyz="{sxyz}" rpy="0 0 0"/></joint>')

    text = re.sub(r'<loop name="([^"]+)" type="spherical">\s*<predecessor name="([^"]+)"><origin xyz="([^"]*)" '
                  r'rpy="0 0 0"/></predecessor>\s*<successor name="platform"><origin xyz="([^"]*)" rpy="0 0 0"/>'
                  r'</successor>\s*</loop>', frames, (DATA / "tilt_head.urdf").read_text())
    assert text.count("closing_") == 12 and "<loop name" not in text
    path = tmp_path / "tilt_closing.urdf"
    path.write_text(text)
    assert_same_robot(pm.load_robot(DATA / "tilt_head.urdf"), pm.load_robot(path))
    cal = _calibrated(pm.load_robot(path), seed=19)
    assert_same_robot(cal, pm.load_robot(rf.export_into(cal, path, tmp_path / "tilt_closing_calibrated.urdf")))


def test_a_3upu_closed_by_connects_is_refused_with_the_reason(tmp_path, capsys):
    """A 3-UPU whose platform-side universal joints end in connects (balls) is three UPS legs: the platform is
    free to turn, no architecture of ours; the message says why and what a 3-UPU needs."""
    path = rf.write_mjcf(pm.load_robot("upu_3"), tmp_path / "upu.xml")
    text = path.read_text()
    welded = re.sub(r'<weld name="([^"]+)" body1="([^"]+)" body2="platform" ?/>',
                    r'<connect name="\1" body1="\2" body2="platform" anchor="0 0 0"/>', text)
    assert welded.count("<connect") == 3
    path.write_text(welded)
    status, _, err = run_cli(["import", path], capsys)
    assert status == 2 and len(err.strip().splitlines()) == 1
    assert "three legs of joints UPS" in err and "ends in a weld to the platform, not a connect" in err

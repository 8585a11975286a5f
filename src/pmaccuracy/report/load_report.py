"""Report section "Clearances under load": the paper's pushes predicted from physics, and a preload.

One section of ``pmaccuracy reproduce`` (:func:`pmaccuracy.report.reproduce`):

(a) the paper's experiment (Sec. 5.2) pushes the platform along +x, -x, +y, -y with the actuators locked;
    each push is a load of :data:`PUSH_N` N (:func:`pmaccuracy.experiment.virtual_rig.predict_pushes`), each
    clearance taken up along its joint's reaction (:func:`pmaccuracy.accuracy.loads.loaded_pose_error`), at
    the home pose for phi in :data:`PHIS_DEG` and both clearance cases; the readings' half-spans (Eq. 23a-b)
    beside the model's worst case at that pose and the paper's simulated values (Sec. 6.1);
(b) a preload (:func:`pmaccuracy.accuracy.loads.design_preload`) for process wrenches in :data:`PROCESS_BOX`
    at the home pose (case 2): the error's range over the box without it, the constant offset with it and
    the unloaded worst case;
(c) the figures of :mod:`pmaccuracy.report.load_figures`: the +y push (the leg it leaves unloaded greyed) and
    the preload.

Every number is stored, JSON-ready, in ``results["loads"]`` (mm, and degrees for keys ending in ``_deg``).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..accuracy.bounds import max_pose_errors
from ..accuracy.loads import Load, design_preload, wrench_set_errors
from ..experiment.measurements import PUSHES
from ..experiment.virtual_rig import predict_pushes
from ..kinematics.workspace import home_pose
from ..model.manipulator import Manipulator
from . import figures
from .document import Document
from .load_figures import plot_load, plot_preload

#: Push force of the virtual experiment (N). To first order the readings do not depend on it (only the signs
#: of the joints' reactions do); it is the force the figure draws.
PUSH_N = 10.0
#: The paper's four pushes shown (its rotations +-r are in results.json).
SHOWN_PUSHES = ("+x", "-x", "+y", "-y")
#: Orientations of the pushes (deg) and clearance cases.
PHIS_DEG, CASES = (0.0, 30.0), ("case1", "case2")
#: Process wrenches of the preload design: the box centre +- half-width [fx N, fy N, m N mm], and its case.
PROCESS_BOX = ((0.0, 0.0, 0.0), (5.0, 5.0, 100.0))
PRELOAD_CASE = "case2"
#: Relative tolerance of "in the paper's range" (the report's 1 % on the paper's printed values).
TOLERANCE = 0.01


def _um(value: float) -> float:
    return round(float(value) * 1e3, 1) + 0.0       # no "-0"


def load_section(doc: Document, robot: Manipulator, out: Path, results: dict, renderer: figures.Renderer, *,
                 paper: tuple = ()) -> None:
    """Append the section to ``doc``, its figures to ``out`` and its numbers to ``results["loads"]``;
    ``paper``: the paper's simulated values (:data:`pmaccuracy.report.PAPER_SIMULATED`) shown beside the
    pushes."""
    home = np.round(home_pose(robot), 9) + 0.0       # a drawing pose; -4e-15 mm would print as such
    doc.heading("Clearances under load: the paper's pushes from physics, and a preload")
    doc.paragraph(
        f"The worst case lets every clearance sit anywhere in its set; under a load each joint's clearance is "
        f"taken up along its reaction, so the pose error becomes one value (the paper's ref. 10). With the "
        f"actuators locked, the legs' wrench intensities solve A^T lambda = -W and each clearance sits at the "
        f"extreme opposite its joint's force; to first order the reached error is the point of the error set "
        f"that maximizes the work W . dX. Here the paper's pushes (Sec. 5.2) are loads of {PUSH_N:g} N at the "
        f"platform centre, at the home pose ({home[0]:.3g}, {home[1]:.3g}) mm; to first order any push force "
        f"gives the same readings (only the signs of the reactions matter). A leg the push leaves unloaded keeps "
        f"its state undetermined: its share of the worst case stays a range (\"+-\" column).")
    pushes = [PUSHES.index(p) for p in SHOWN_PUSHES]
    rows, comparison, data = [], [], {"push_n": PUSH_N, "home": [float(home[0]), float(home[1])], "pushes": {}}
    paper_of = {(p.case, p.phi_deg, p.quantity): p for p in paper}
    for case in CASES:
        for phi_deg in PHIS_DEG:
            pose = np.array([home[0], home[1], math.radians(phi_deg)])
            d, spread = predict_pushes(robot, case, pose[None], PUSH_N)
            d, spread = d[0], spread[0]
            b = max_pose_errors(robot, case, pose[None])
            key = f"{case}/{phi_deg:g}"
            data["pushes"][key] = {p: {"dx": float(d[k, 0]), "dy": float(d[k, 1]),
                                       "dphi_deg": math.degrees(d[k, 2]),
                                       "spread": [float(spread[k, 0]), float(spread[k, 1]),
                                                  math.degrees(spread[k, 2])]} for k, p in enumerate(PUSHES)}
            for k in pushes:
                rng = ", ".join(f"{name} +-{v}" for name, v in
                                (("dx", _um(spread[k, 0])), ("dy", _um(spread[k, 1])),
                                 ("dphi", round(math.degrees(spread[k, 2]), 4))) if v) or "-"
                rows.append([case, f"{phi_deg:g}", PUSHES[k], _um(d[k, 0]), _um(d[k, 1]),
                             round(math.degrees(d[k, 2]), 4) + 0.0, rng])
            half = {"dx": (d[0, 0] - d[1, 0]) / 2, "dy": (d[2, 1] - d[3, 1]) / 2}
            worst = {"dx": float(b.dx_max[0]), "dy": float(b.dy_max[0])}
            for q in ("dx", "dy"):
                ref = paper_of.get((case, phi_deg, f"{q}_max"))
                within = "-" if ref is None else \
                    "PASS" if ref.lo * (1 - TOLERANCE) <= half[q] <= ref.hi * (1 + TOLERANCE) else "outside"
                comparison.append([case, f"{phi_deg:g}", f"{q} (+-{q[1]} pushes)", round(float(half[q]), 4),
                                   round(worst[q], 4),
                                   "-" if ref is None else (f"{ref.lo:.3f}" if ref.lo == ref.hi else
                                                            f"{ref.lo:.3f} to {ref.hi:.3f} (over the workspace)"),
                                   within])
                data["pushes"][key][f"half_span_{q}"] = float(half[q])
                data["pushes"][key][f"{q}_max"] = worst[q]
    doc.table(["case", "phi [deg]", "push", "dx [um]", "dy [um]", "dphi [deg]", "unloaded legs' range"], rows)
    doc.paragraph(
        "The paper measures the error at a point as the spread of the readings of opposite pushes (Eq. 23a-b). "
        "Predicted from physics, half that spread beside the worst case at the same pose and the value the "
        "paper simulates (Sec. 6.1; it gives them for case 1 at phi = 0 only):")
    doc.table(["case", "phi [deg]", "quantity", "half the push spread [mm]", "worst case at the pose [mm]",
               "paper, simulated max [mm]", f"in the paper's range (+-{TOLERANCE:.0%})"], comparison)
    first = data["pushes"][f"{CASES[0]}/{PHIS_DEG[0]:g}"]
    part = [p for p in SHOWN_PUSHES if max(first[p]["spread"][:2]) > 1e-9]     # > 1e-6 um: a leg unloaded
    full = [p for p in SHOWN_PUSHES if p not in part]
    reading = (f"The pushes {', '.join(full)} load every leg: each reading is an extreme of the error set, so "
               f"their spread measures the worst case. " if full else "")
    if part:
        worst_part = max(part, key=lambda p: first[p]["spread"][0])
        reading += (f"The pushes {', '.join(part)} leave a leg unloaded: its share stays a range (the {worst_part} "
                    f"push leaves x anywhere within +-{_um(first[worst_part]['spread'][0])} um, {CASES[0]}, phi = "
                    f"{PHIS_DEG[0]:g} deg), so a measured reading there depends on friction and on how the push "
                    f"was applied, not on the clearances alone.")
    doc.paragraph(reading)
    fig_push = doc.figure(
        renderer.submit(out / "load_push_y.png", plot_load, robot, "case2", home, Load(fy=PUSH_N)),
        f"The +y push of {PUSH_N:g} N on the platform (case 2, home pose): the joints' forces (arrows at the "
        f"stated scale), each joint's contact state (pins in their bores, the P blocks' rhombus vertices; "
        f"enlarged), the unloaded leg greyed, and the loaded platform magnified (factor in the legend).")
    # ---------------------------------------------------------------- preload
    center, half = (np.array(v, dtype=float) for v in PROCESS_BOX)
    pre = design_preload(robot, PRELOAD_CASE, home, center, half)
    box = wrench_set_errors(robot, PRELOAD_CASE, home[None], center, half)
    without = box.upper[0] - box.lower[0]
    flips = ", ".join(str(i + 1) for i in range(3) if box.flips[0, i]) or "none"
    to_deg = np.array([1.0, 1.0, 180.0 / math.pi])
    doc.paragraph(
        f"**Preload.** A process pushing back with fx, fy in [{center[0] - half[0]:g}, {center[0] + half[0]:g}] N "
        f"and m in [{center[2] - half[2]:g}, {center[2] + half[2]:g}] N mm ({PRELOAD_CASE}, home pose) flips the "
        f"contact of legs {flips}, so the clearance error is a range. The smallest constant wrench that keeps "
        f"every leg's reaction on one side for every process wrench (a linear program; Figure {fig_push + 1}) "
        f"is fx = {pre.wrench[0] + 0:.3g} N, fy = {pre.wrench[1] + 0:.3g} N, m = {pre.wrench[2] + 0:.3g} N mm "
        f"(size {pre.size:.3g} N, with m counted over the robot's size {robot.characteristic_length:g} mm): the "
        f"error is then a constant offset, which calibration removes.")
    labels = ("dx [mm]", "dy [mm]", "dphi [deg]")
    doc.table(["quantity", "range over the process box, no preload", "range with the preload",
               "constant offset with the preload", "unloaded worst case (+-max)"],
              [[labels[j], round(float(without[j] * to_deg[j]), 4), 0, round(float(pre.offset[j] * to_deg[j]), 4),
                f"+-{pre.worst[j] * to_deg[j]:.4f}"] for j in range(3)])
    doc.figure(renderer.submit(out / "load_preload.png", plot_preload, robot, PRELOAD_CASE, home, center, half),
               "The preload for the process box: the legs whose contact flips without it (orange), the preload "
               "(green) and the process forces' box at the same scale; right, the error's range without and with "
               "the preload beside the unloaded worst case.")
    data["preload"] = {"case": PRELOAD_CASE, "box_center": center.tolist(), "box_half": half.tolist(),
                       "wrench": [float(v) + 0.0 for v in pre.wrench], "size_n": pre.size,
                       "flipping_legs": [i + 1 for i in range(3) if box.flips[0, i]],
                       "range_without": [float(without[0]), float(without[1]), math.degrees(without[2])],
                       "offset": [float(pre.offset[0]), float(pre.offset[1]), math.degrees(pre.offset[2])],
                       "worst": [float(pre.worst[0]), float(pre.worst[1]), math.degrees(pre.worst[2])]}
    results["loads"] = data


__all__ = ["load_section"]

"""The text of the report section "Design decisions" (:mod:`pmaccuracy.report.design_report`): the verdict and
parts (a)-(e), written from the section's results alone.

Every sentence is computed from ``d = results["design_decisions"]`` (mm, deg; relative gaps and excesses as
fractions): :func:`trust` gives how far the first-order model can be trusted from the tables, :func:`_verdict`
reads its numbers from them, and a part whose result holds an ``error`` is written as a box
(:meth:`pmaccuracy.report.document.Document.failure`) naming it and the reason.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.manipulator import Manipulator
from .document import Document


def _fmt(v, digits: int = 4) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def _pct(v, digits: int = 3) -> str:
    """A ratio as a percentage without the sign (the column header says [%])."""
    return "-" if v is None else f"{100 * v:.{digits}f}"


def _pose(x: float, y: float, phi_deg: float) -> str:
    return f"({x:.4g}, {y:.4g}, {phi_deg:.3g})"


def span(values, digits: int = 2, sep: str = "-") -> str:
    """``"a-b"`` of the smallest and largest of ``values`` at ``digits`` decimals, or one value when both ends
    print the same.

    >>> span([0.2412, 0.2398]), span([0.1, 0.25])
    ('0.24', '0.10-0.25')
    """
    lo, hi = f"{min(values):.{digits}f}", f"{max(values):.{digits}f}"
    return lo if lo == hi else f"{lo}{sep}{hi}"


def trust(d: dict) -> dict:
    """How far the first-order model can be trusted at the section's clearances, from the section's own numbers:
    ``poses_excess`` the largest relative excess of the certified dp over first order at the poses of (a) (last
    case, first scale), ``map_excess`` the largest one over the certified map of (a') (which includes the bound's
    own gap), ``map_gap`` the certified map's largest gap; each ``None`` where not computed; ``usable`` when the
    largest of them is below 1 %."""
    s = d["settings"]
    last = s["cases"][-1]
    at1 = [r for r in d["certified"] if r["scale"] == s["scales"][0] and r["case"] == last
           and r["quantities"]["dp"]["certified"] is not None]
    poses = max(((r["quantities"]["dp"]["certified"] - r["quantities"]["dp"]["first_order"])
                 / r["quantities"]["dp"]["first_order"] for r in at1), default=None)
    cm = d.get("certified_map") or {}
    layers = [L for L in (cm.get("layers") or {}).values() if L["dp"]["excess"] is not None]
    excess = max((L["dp"]["excess"] for L in layers), default=None)
    gap = max((L[q]["gap"] for L in layers for q in ("dx", "dy", "dphi_deg", "dp")), default=None)
    known = [v for v in (poses, excess) if v is not None]
    return {"poses_excess": poses, "map_excess": excess, "map_gap": gap,
            "usable": bool(known) and max(known) < 0.01}


def _verdict(d: dict) -> str:
    """Three lines a designer reads first: the certified worst case, the targets, how far the maps can be
    trusted (every number from the section's own results: :func:`trust`, ``global_worst``, ``synthesis``)."""
    s = d["settings"]
    lo, hi = s["phi_range_deg"]
    last = s["cases"][-1]
    if "error" in d["global_worst"][last]:
        gw = None
        line1 = (f"**Verdict.** (1) With the clearances `{last}` the worst case over {s['region']} at phi in "
                 f"[{lo:g}, {hi:g}] deg could not be bounded: {d['global_worst'][last]['error']}")
    elif any(d["global_worst"][last]["quantities"][q]["upper"] is None for q in ("dp", "dphi_deg")):
        gw = d["global_worst"][last]["quantities"]
        dp = gw["dp"]
        line1 = (f"**Verdict.** (1) With the clearances `{last}` the worst case over {s['region']} at phi in "
                 f"[{lo:g}, {hi:g}] deg has no finite certified bound: the errors found reach dp = "
                 f"{dp['lower']:.4g} mm at {_pose(dp['x'], dp['y'], dp['phi_deg'])}, where the region comes "
                 "(nearly) to a singularity. Narrow the region (`--disc`, `--box`, `--polygon`, `--phi-range-deg`) "
                 "to certify the rest.")
    else:
        gw = d["global_worst"][last]["quantities"]
        dp, dphi = gw["dp"], gw["dphi_deg"]
        line1 = (f"**Verdict.** (1) With the clearances `{last}`, no pose of {s['region']} at phi in [{lo:g}, "
                 f"{hi:g}] deg errs by more than dp = {_fmt(dp['upper'])} mm or dphi = {_fmt(dphi['upper'])} deg "
                 f"(certified; attained {_fmt(dp['lower'])} mm at {_pose(dp['x'], dp['y'], dp['phi_deg'])}).")
    syn_error = next((v["error"] for v in (d["synthesis"] or {}).values() if "error" in v), None)
    if syn_error:
        line2 = f" (2) The clearances could not be sized for the targets: {syn_error}"
    elif d["synthesis"]:
        uni = d["synthesis"]["uniform"]
        tgt = ", ".join(f"{k} <= {v:g} {'deg' if k.endswith('_deg') else 'mm'}" for k, v in s["targets"].items())
        meets = gw is not None and all(gw[k]["upper"] is not None and gw[k]["upper"] <= v
                                       for k, v in s["targets"].items())
        line2 = (f" (2) Against the targets {tgt}: `{last}` {'meets' if meets else 'misses'} them; the clearances "
                 f"of `{uni['template']}` may be scaled by {uni['scale']:.3g} (uniformly) and still meet them "
                 "everywhere, certified.")
    else:
        line2 = " (2) No targets were given (`--target`), so the clearances were not sized."
    t = trust(d)
    said = []
    if t["poses_excess"] is not None:
        said.append(f"the exact model exceeds the first-order worst case by at most {_pct(t['poses_excess'], 2)} % "
                    "at the poses of (a)")
    if t["map_excess"] is not None:
        said.append(f"over the certified map of {s['region']} the certified bound lies at most "
                    f"{_pct(t['map_excess'], 2)} % above first order (the exact excess plus the bound's own gap, up "
                    f"to {_pct(t['map_gap'], 2)} %)")
    if not said:
        line3 = " (3) The exact model could not be certified at these clearances: see the reasons in (a)."
    else:
        line3 = (" (3) At these clearances " + "; ".join(said)
                 + (": the first-order maps can be used as they are." if t["usable"] else
                    ": where that matters, use the certified values rather than the first-order maps."))
    return line1 + line2 + line3


def _poses_text(d: dict) -> str:
    """Which poses table (a) holds, from the labels of its rows."""
    labels = list(dict.fromkeys(r["label"] for r in d["certified"]))
    ref = d["settings"]["reference_pose"]
    where = "the home pose" if ref["label"] == "home" else \
        f"the well-conditioned point nearest to the region's centre ({ref['x']:.4g}, {ref['y']:.4g})"
    others = [lab for lab in labels if lab not in ("home", "centre of the region")]
    text = f"Poses: {where}" + (", " + ", ".join(f"the {lab}" for lab in others) if others else "")
    left = 3 - len(labels)
    if left > 0:
        text += (f" ({left} more {'pose was' if left == 1 else 'poses were'} left out: the worst candidates lie "
                 f"within a condition number of {d['settings']['well_conditioned']:g} of a singularity, where the linear model "
                 "no longer describes the robot)")
    return text + " (first-order dp decides which is worst)."


def _write_certified(doc: Document, d: dict) -> None:
    """(a): the certified worst cases at the poses of :func:`check_poses` and their reading."""
    s = d["settings"]
    doc.paragraph(
        "**(a) Certified worst cases of the exact model.** The maps use the paper's first-order model. The exact "
        "loop closure differs by the Taylor remainder: `nonlinear` is the largest error of a feasible clearance "
        "configuration (attained, a lower bound of the exact worst case), `certified` a rigorous upper bound of "
        f"it (`pmaccuracy bounds --certified`), `gap` their relative difference. {_poses_text(d)} Values in mm "
        "and deg.")
    rows = []
    for r in d["certified"]:
        p = r["pose"]
        dp, dphi = r["quantities"]["dp"], r["quantities"]["dphi_deg"]
        fo = dp["first_order"]
        excess = None if dp["certified"] is None else (dp["certified"] - fo) / fo
        rows.append([r["case"], f"{r['scale']:g}x", r["label"], _pose(p["x"], p["y"], p["phi_deg"]),
                     _fmt(fo, 5), _fmt(dp["nonlinear"], 5), _fmt(dp["certified"], 5), _pct(dp["gap"]),
                     _pct(excess), _fmt(dphi["first_order"], 5), _fmt(dphi["certified"], 5),
                     _pct(dphi["gap"])])
    doc.table(["case", "clearances", "pose", "(x, y, phi)", "dp first-order", "dp nonlinear", "dp certified",
               "dp gap [%]", "certified above first-order [%]", "dphi first-order", "dphi certified",
               "dphi gap [%]"], rows)
    ex, gaps = {}, {}
    for sc in s["scales"]:
        at = [r for r in d["certified"] if r["scale"] == sc and r["quantities"]["dp"]["certified"] is not None]
        ex[sc] = max(((r["quantities"]["dp"]["certified"] - r["quantities"]["dp"]["first_order"])
                      / r["quantities"]["dp"]["first_order"] for r in at), default=None)
        gaps[sc] = max((r["quantities"][q]["gap"] for r in at for q in ("dp", "dphi_deg")
                        if r["quantities"][q]["gap"] is not None), default=None)
    sc0, sc1 = s["scales"][0], s["scales"][-1]
    if ex[sc0] is None or ex[sc1] is None:
        doc.paragraph("**Reading.** Some poses could not be certified (the table shows `-`): see the reasons in "
                      "`results.json` (`design_decisions.certified[].reason`).")
        return
    clearances = "the paper" + chr(39) + "s" if s["paper_cases"] else "the given"
    doc.paragraph(
        f"**Reading.** At {clearances} clearances the exact worst case of dp exceeds the first-order one by at "
        f"most {_pct(ex[sc0])} % at these poses and dp, dphi are known to {_pct(gaps[sc0])} %"
        + (": the first-order values can be used as they are there." if ex[sc0] < 0.01 else
           ": use the certified values.")
        + f" At {sc1:g}x the clearances the excess reaches {_pct(ex[sc1], 2)} % (the remainder grows with the "
        f"square of the clearances) and the gap {_pct(gaps[sc1], 2)} %: add that margin to a first-order budget "
        "for loose joints, or use the certified value.")


def _write_certified_map(doc: Document, d: dict, cert_figure: Path | None) -> None:
    """(a'): the certified map over the region, with its figure."""
    s, cm = d["settings"], d["certified_map"]
    parts = []
    for phi, L in cm["layers"].items():
        if L["dp"]["certified"] is None:
            parts.append(f"at phi = {phi} deg no grid point of the region is certified")
            continue
        parts.append(f"at phi = {phi} deg dp up to {_fmt(L['dp']['certified'][1])} mm and dphi up to "
                     f"{_fmt(L['dphi_deg']['certified'][1])} deg, at most {_pct(L['dp']['excess'], 2)} % "
                     f"(dp) above the first-order maximum, largest gap "
                     f"{_pct(max(L[q]['gap'] for q in ('dx', 'dy', 'dphi_deg', 'dp')), 2)} %, "
                     f"{L['certified_points']} of {L['points']} grid points certified")
    coarse = (f", coarsened from the maps' {cm['report_grid']} x {cm['report_grid']} to stay within about "
              f"{cm['budget_s']:g} s (`pmaccuracy map --certified --grid N` for a finer one)"
              if cm["grid"] < cm["report_grid"] else "")
    doc.paragraph(
        f"**(a') Certified maps.** The same bounds over {cm['region']} ({cm['case']}, a {cm['grid']} x "
        f"{cm['grid']} grid{coarse}; {cm['seconds']:.1f} s): " + "; ".join(parts)
        + ". The excess over first order includes the bound's own gap; it is largest near a singular edge, where "
          "the linear model no longer describes the robot. A grid point not certified is left blank (NaN), never "
          "filled with a guess.")
    if cm.get("figure") and cert_figure is not None:
        doc.figure(cert_figure, f"{cm['case']}: certified upper bound of the exact worst-case |dp| over "
                                f"{cm['region']} (left) and how far it lies above the first-order maximum (right, "
                                "%): the exact model's excess plus the bound's own gap (refined only to 0.1 %, "
                                "hence the bands).")


def _write_global(doc: Document, d: dict, ok: dict) -> None:
    """(b): the certified global maxima over the region, beside the grid maxima over the same region."""
    s = d["settings"]
    lo, hi = s["phi_range_deg"]
    gw_rows = []
    for c, gw in ok.items():
        for key, w in gw["quantities"].items():
            best = w.get("grid_best")
            miss = None if best is None or not w["lower"] else (w["lower"] - best) / w["lower"]
            gw_rows.append([c, key, _fmt(w["lower"], 5), _fmt(w["upper"], 5), _pct(w["gap"], 2),
                            _pose(w["x"], w["y"], w["phi_deg"]), _fmt(best, 5),
                            "-" if miss is None else f"{round(100 * miss, 2) + 0.0:.2f}",
                            "yes" if w["converged"] else "no"])
    orients = next(iter(ok.values())).get("grid_orientations_deg") or []
    orient = ", ".join(f"{p:g}" for p in orients)
    grid_note = (f"The report's maps sample the same region on a grid at phi = {orient} deg only; `grid max` is "
                 "their largest value there and the next column how far it lies below the attained maximum "
                 "(negative: the grid found a larger value than the search's attained one, still below the "
                 "certified max)." if orients else
                 "No orientation of the report's maps lies in the interval, so there is no grid value to compare.")
    doc.paragraph(
        f"**(b) Global maximum over {s['region']} for phi in [{lo:g}, {hi:g}] deg** (`pmaccuracy worst`, "
        "first-order model): `attained` is the value at the pose shown, `certified max` a rigorous bound over "
        "every reachable pose of the region (branch and bound with interval arithmetic), `gap` their relative "
        f"difference. {grid_note}")
    doc.table(["case", "quantity", "attained", "certified max", "gap [%]", "at (x, y, phi)", "grid max",
               "grid max below attained [%]", "certified"], gw_rows)
    ws = [w for gw in ok.values() for w in gw["quantities"].values()]
    misses = [(w["lower"] - w["grid_best"]) / w["lower"] for w in ws if w.get("grid_best") is not None
              and w["lower"]]
    gaps = [w["gap"] for w in ws if w["gap"] is not None]
    at_end = sum(min(abs(w["phi_deg"] - lo), abs(w["phi_deg"] - hi)) < 1e-6 for w in ws)
    phis = ", ".join(f"{p:.3g}" for p in sorted({round(w["phi_deg"], 6) + 0.0 for w in ws}))
    if misses and max(misses) < 1e-3:
        grid_text = (f"the maps' grid at phi = {orient} deg already comes within "
                     f"{_pct(max(max(misses), 0.0), 2)} % of every maximum over the region")
    elif misses:
        grid_text = (f"the maps' grid at phi = {orient} deg underestimates a maximum over the region by up to "
                     f"{_pct(max(misses), 1)} %")
    else:
        grid_text = "the maps give no grid value to compare"
    unbounded = [w for w in ws if w["upper"] is None or w["gap"] is None]
    guarantee = (f"What the certificate adds is the guarantee: no pose of the region, at any orientation in between, "
                 f"is worse than `certified max`, at most {_pct(max(gaps), 2)} % above the attained value. That is "
                 "the number to compare with a specification over the whole task space."
                 if not unbounded else
                 f"{len(unbounded)} of {len(ws)} maxima have no finite certified bound (`-`): the region reaches a "
                 "singularity, where the errors are unbounded; cut the region away from it (`--disc`, `--box`, "
                 "`--polygon`) to certify the rest.")
    doc.paragraph(
        f"**Reading.** The maxima are attained at phi = {phis} deg ({at_end} of {len(ws)} at an end of the "
        f"interval); {grid_text}. {guarantee}")


def write(doc: Document, robot: Manipulator, d: dict, figure: Path, cert_figure: Path | None = None) -> None:
    s = d["settings"]
    lo, hi = s["phi_range_deg"]
    doc.heading("Design decisions: certified worst cases, global maxima, tolerance synthesis, statistics")
    doc.paragraph(_verdict(d))
    doc.paragraph(
        f"What a designer of `{robot.name}` needs to fix the clearances over {s['region']}: how much the "
        "first-order worst case can be trusted, the certified worst case over the region, the largest clearances "
        "meeting a target, and how often the errors come near the worst case. Settings (coarse, for run time): "
        f"global maxima and synthesis certified to a gap of {100 * s['gap']:g} %, {s['pose_samples']} samples at "
        f"the pose, a {s['map_grid']} x {s['map_grid']} percentile map of {s['map_samples']} samples, seed "
        f"{s['seed']}. This section took {d['seconds']:.1f} s.")
    # (a) -----------------------------------------------------------------------------------------------------
    for case, reason in (d.get("certified_errors") or {}).items():
        doc.failure(f"(a) Certified worst cases, clearances {case}", reason)
    if d["certified"]:
        _write_certified(doc, d)
    cm = d.get("certified_map")
    if cm and "error" in cm:
        doc.failure(f"(a') Certified map over {s['region']}", cm["error"])
    elif cm:
        _write_certified_map(doc, d, cert_figure)
    # (b) -----------------------------------------------------------------------------------------------------
    ok = {c: gw for c, gw in d["global_worst"].items() if "error" not in gw}
    for c, gw in d["global_worst"].items():
        if "error" in gw:
            doc.failure(f"(b) Global maximum over {s['region']} for phi in [{lo:g}, {hi:g}] deg, clearances {c}",
                        gw["error"])
    if ok:
        _write_global(doc, d, ok)
    # (c) -----------------------------------------------------------------------------------------------------
    errors = [v["error"] for v in (d["synthesis"] or {}).values() if "error" in v]
    if errors:
        doc.failure("(c) Tolerance synthesis", errors[0])
    if d["synthesis"] and not errors:
        syn = d["synthesis"]
        uni, mc = syn["uniform"], syn["min-cost"]
        tgt = ", ".join(f"{k} = {v:g} {'deg' if k.endswith('_deg') else 'mm'}" for k, v in s["targets"].items())
        doc.paragraph(
            f"**(c) Tolerance synthesis** (`pmaccuracy synthesize`): the largest clearances of the template "
            f"`{uni['template']}` (its non-zero sources) that keep the certified worst case within {tgt} everywhere in {s['region']} for phi in "
            f"[{lo:g}, {hi:g}] deg. Uniform: the template times one factor; min-cost: per joint, minimizing "
            f"sum eps0 / eps (halving a clearance doubles its cost), equal weights, {mc['cuts']} cutting plane(s) "
            f"(the report stops at {s['max_cuts']}; `pmaccuracy synthesize --mode min-cost` goes on: the design "
            "is certified either way, fewer cuts leave it more conservative). Values in mm or rad by the source.")
        doc.table(["source", "template", "uniform", "min-cost"],
                  [[a["source"], f"{a['template']:.6g}", f"{a['value']:.6g}", f"{b['value']:.6g}"]
                   for a, b in zip(uni["sources"], mc["sources"])])
        ver = []
        for key in ("dx", "dy", "dphi_deg", "dp"):
            target = s["targets"].get(key)
            ver.append([key, "-" if target is None else f"{target:g}", _fmt(uni["worst"][key]["upper"], 5),
                        _fmt(mc["worst"][key]["upper"], 5)])
        doc.paragraph("Re-verified certified worst cases of the synthesized clearances (mm, deg):")
        doc.table(["quantity", "target", "uniform", "min-cost"], ver)
        binding = [k for k, t in s["targets"].items() if uni["worst"][k]["upper"] >= t * (1 - 2 * s["gap"])]
        looser = [b["source"] for a, b in zip(uni["sources"], mc["sources"]) if b["value"] > a["value"] * (1 + 1e-4)]
        tighter = [b["source"] for a, b in zip(uni["sources"], mc["sources"]) if b["value"] < a["value"] * (1 - 1e-4)]
        change = (f"loosens {', '.join(looser) or 'nothing'} and tightens {', '.join(tighter) or 'nothing'}"
                  if looser or tighter else "is the uniform one to 0.01 %")
        doc.paragraph(
            f"**Reading.** Uniform scaling allows {uni['scale']:.4f} times the template "
            f"({'binding: ' + ', '.join(binding) if binding else 'no target binding'}). The min-cost design "
            f"{change}, cost {mc['cost']:.4f} against "
            f"{len(uni['sources']) / uni['scale']:.4f} for the uniform one. Both are certified over the whole "
            f"region; with a {100 * s['gap']:g} % certificate they are conservative by at most that much.")
    # (d) -----------------------------------------------------------------------------------------------------
    stats = {c: st for c, st in d["statistics"].items() if "error" not in st}
    for c, st in d["statistics"].items():
        if "error" in st:
            doc.failure(f"(d) Statistics, clearances {c}", st["error"])
    last = stats.get(s["cases"][-1])
    if stats:
        st_rows = []
        for c, st in stats.items():
            q = st["pose"]["quantities"]["dp"]
            st_rows.append([c, _fmt(q["mean"]), _fmt(q["std"]), _fmt(q["rss"]),
                            f"{q['p95']:.4f} [{q['p95_lo']:.4f}, {q['p95_hi']:.4f}]",
                            f"{q['p99']:.4f} [{q['p99_lo']:.4f}, {q['p99_hi']:.4f}]",
                            f"{q['exceed']:.4f} +- {q['se_exceed']:.4f}", _fmt(q["worst"])])
        hp = next(iter(stats.values()))["pose"]["pose"]
        where = "the home pose" if s["reference_pose"]["label"] == "home" else "the region's reference pose"
        doc.paragraph(
            f"**(d) Statistics beside the worst case** at {where} ({hp['x']:.4g}, {hp['y']:.4g}, "
            f"{hp['phi_deg']:g}): every clearance independent and uniform in its set, first-order model, "
            f"{s['pose_samples']} samples. |dp| in mm; percentiles with their 95 % interval, the exceedance "
            f"P(|dp| > {s['threshold_dp']:g} mm) with its standard error; `rss` is the analytic root mean square "
            "sqrt(var dx + var dy).")
        doc.table(["case", "mean |dp|", "std |dp|", "rss", "p95", "p99", f"P(|dp| > {s['threshold_dp']:g})",
                   "worst case"], st_rows)
    if last is not None:
        reg = next(iter(last["region"]["orientations"].values()))
        q2 = last["pose"]["quantities"]["dp"]
        typical = [st["pose"]["quantities"]["dp"]["mean"] / st["pose"]["quantities"]["dp"]["worst"]
                   for st in stats.values()]
        doc.paragraph(
            f"**Reading.** The mean error is {span(typical)} times the worst case; 99 % of the "
            f"clearance states stay within {100 * q2['p99'] / q2['worst']:.0f} % of it ({s['cases'][-1]}). "
            f"Over {s['region']} at phi = 0 the 95th percentile of |dp| is on average "
            f"{reg['dp']['p95_over_max']:.2f} times the worst case, and at the pose above "
            f"{100 * q2['exceed']:.2f} % of the states exceed {s['threshold_dp']:g} mm. Designing to the worst "
            "case is therefore conservative for almost every clearance state; it is what a guarantee needs, while "
            "the percentiles tell how often a looser design would miss a specification.")
        if last.get("figure"):
            doc.figure(figure, f"{s['cases'][-1]}, phi = 0, over {s['region']}: 95th percentile of |dp| and "
                               f"|dphi| ({s['map_samples']} samples per point), their worst case and the ratio.")
    # (e) -----------------------------------------------------------------------------------------------------
    if d["iso9283"] and "error" in d["iso9283"]:
        doc.failure("(e) ISO 9283 pose accuracy and repeatability", d["iso9283"]["error"])
    elif d["iso9283"]:
        iso = d["iso9283"]
        iso_rows = [[r["point"], f"({r['x_nom']:g}, {r['y_nom']:g})", r["n"], _fmt(r["ap_p"]), _fmt(r["rp_l"]),
                     f"{r['rp_l_model']:.4f} [{r['rp_l_model_lo']:.4f}, {r['rp_l_model_hi']:.4f}]",
                     _fmt(r["rp_phi_deg"]),
                     f"{r['rp_phi_model_deg']:.4f} [{r['rp_phi_model_lo_deg']:.4f}, {r['rp_phi_model_hi_deg']:.4f}]",
                     _fmt(r["dp_max"])] for r in iso["points"]]
        doc.paragraph(
            f"**(e) ISO 9283 pose accuracy and repeatability** from a virtual test (`experiment simulate --repeats "
            f"{s['iso']['cycles']}`): {len(iso['points'])} points at phi = 0, {s['iso']['cycles']} cycles each, "
            f"clearances {s['iso']['clearances']}, every cycle a fresh uniform clearance state, exact loop closure, "
            f"camera noise {s['iso']['noise_mm']:g} mm / {s['iso']['noise_deg']:g} deg. Beside the simulated test's AP_p (ISO "
            "9283: the offset of the barycentre of the attained positions) and RP the model's predicted RP (mean of 2000 simulated tests, with the 5-95 % range of one test), and the "
            "worst case dp_max. mm and deg.")
        doc.table(["point", "(x, y)", "cycles", "AP_p", "RP_l", "RP_l model [5-95 %]", "RP_phi", "RP_phi model [5-95 %]",
                   "dp_max"], iso_rows)
        ratio = np.mean([r["rp_l"] / r["rp_l_model"] for r in iso["points"]])
        rl = [r["rp_l"] / r["dp_max"] for r in iso["points"]]
        rphi = [r["rp_phi_deg"] / r["dphi_max_deg"] for r in iso["points"]]
        doc.paragraph(
            f"**Reading.** {100 * iso['share_rp_l_in_model_range']:.0f} % of the simulated RP_l lie in the model's "
            f"range for one test (mean ratio simulated / predicted {ratio:.2f}): "
            + ("the clearance model explains the scatter. " if iso["share_rp_l_in_model_range"] >= 0.6
               else "the scatter departs from the clearance model. ")
            + f"AP_p is only the barycentre's scatter: symmetric clearances cause no systematic offset. RP_l "
            f"is {span(rl)} times the worst case dp_max and RP_phi {span(rphi)} "
            "times dphi_max: an ISO repeatability figure is of the order of the worst case but neither bounds it "
            "nor is bounded by it, since it counts the spread of random states (3 standard deviations), not the "
            "extreme configuration.")

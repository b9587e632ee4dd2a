#!/usr/bin/python3
"""Are sinew-track's error bars honest? On rendered sequences with exact mechanics (the shared
whisker_pad renderer's truth.json), for every truth whisker-frame in contact that the tracker
matched and found a contact load for: the standardised error z = (value − truth) / SD of the
contact moment (contact_moment_N_m, contact_moment_sd_N_m) and the contact force's magnitude
(contact_force_N, contact_force_sd_N), and of the curvature moment (m0_N_m, m0_sd_N_m). Calibrated
error bars put the truth within ±2 SD on about 95 % of them (issue 49 asks 90–98 %). On matched
whisker-frames without contact, the fraction with |m0_N_m| ≤ 3 m0_sd_N_m (issue 49 asks ≥ 99 %).

  whisker_error_bars.py RENDER_DIR RESULTS.jsonl [RENDER_DIR RESULTS.jsonl ...] [--json OUT]

A tracked whisker matches the truth whisker its nodes lie closest to (mean distance to the true
centreline), within 3 px. The moment's sign follows the truth's conventions (counter-clockwise on
screen positive: Sinew's image-axis moment times −1, as the renderer's scorer reads it).
"""
import argparse
import json
import math
import sys

import numpy as np

GATE_PX = 3.0


def polyline_distance(points, line):
    """Distance from each of points (n, 2) to the polyline line (m, 2)."""
    a, b = line[:-1], line[1:]
    ab = b - a
    l2 = np.maximum(np.sum(ab * ab, 1), 1e-18)
    t = np.clip(np.einsum("nmk,mk->nm", points[:, None, :] - a[None], ab) / l2, 0, 1)
    proj = a[None] + t[..., None] * ab[None]
    return np.min(np.linalg.norm(points[:, None, :] - proj, axis=2), axis=1)


def read_results(path):
    rows = {}
    with open(path) as f:
        for line in f:
            if line.strip():
                r = json.loads(line)
                if "frame" in r:
                    rows[int(r["frame"])] = r
    return rows


def case_figures(render_dir, results_path):
    with open(f"{render_dir}/truth.json") as f:
        truth = json.load(f)
    rows = read_results(results_path)
    z_moment, z_force, rel_moment, rel_sd, z_m0, quiet_m0 = [], [], [], [], [], []
    contact_frames = missing = 0
    for fr in truth["frames"]:
        tracked = [w for w in rows.get(fr["frame"], {}).get("whiskers", [])
                   if w.get("status", "ok") == "ok" and w.get("nodes")]
        for tw in fr["whiskers"]:
            line = np.asarray(tw["nodes"], float)
            best, best_d = None, GATE_PX
            for w in tracked:
                d = float(np.mean(polyline_distance(np.asarray(w["nodes"], float)[:, :2], line)))
                if d < best_d:
                    best, best_d = w, d
            m0_sd = best.get("m0_sd_N_m") if best else None
            if not tw["contact"]:
                if m0_sd:
                    quiet_m0.append(abs(best["m0_N_m"]) / m0_sd)
                continue
            contact_frames += 1
            if m0_sd:
                z_m0.append(abs(-best["m0_N_m"] - tw["M0_Nm"]) / m0_sd)
            if best is None or best.get("contact_moment_sd_N_m") is None:
                missing += 1
                continue
            m, m_sd = -best["contact_moment_N_m"], best["contact_moment_sd_N_m"]
            f, f_sd = float(np.hypot(*best["contact_force_N"])), best["contact_force_sd_N"]
            z_moment.append((m - tw["M0_Nm"]) / m_sd if m_sd > 0 else math.inf)
            z_force.append((f - tw["contact_force_N"]) / f_sd if f_sd > 0 else math.inf)
            if abs(tw["M0_Nm"]) > 0:
                rel_moment.append(abs(m - tw["M0_Nm"]) / abs(tw["M0_Nm"]))
                rel_sd.append(m_sd / abs(tw["M0_Nm"]))
    z_moment, z_force = np.abs(np.asarray(z_moment)), np.abs(np.asarray(z_force))
    n = len(z_moment)
    return {
        "case": f"{truth.get('case')} s{truth.get('seed')}",
        "contact_whisker_frames": contact_frames,
        "with_load": n,
        "missing": missing,
        "moment_within_2sd": float(np.mean(z_moment <= 2.0)) if n else math.nan,
        "force_within_2sd": float(np.mean(z_force <= 2.0)) if n else math.nan,
        "moment_median_abs_z": float(np.median(z_moment)) if n else math.nan,
        "moment_median_rel_error": float(np.median(rel_moment)) if rel_moment else math.nan,
        "moment_median_rel_sd": float(np.median(rel_sd)) if rel_sd else math.nan,
        "m0_within_2sd": float(np.mean(np.asarray(z_m0) <= 2.0)) if z_m0 else math.nan,
        "quiet_frames": len(quiet_m0),
        "quiet_m0_within_3sd": float(np.mean(np.asarray(quiet_m0) <= 3.0)) if quiet_m0 else math.nan,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pairs", nargs="+", help="RENDER_DIR RESULTS.jsonl, repeated")
    ap.add_argument("--json", help="write the rows here")
    a = ap.parse_args()
    if len(a.pairs) % 2:
        sys.exit("give RENDER_DIR RESULTS.jsonl pairs")
    rows = [case_figures(a.pairs[i], a.pairs[i + 1]) for i in range(0, len(a.pairs), 2)]
    print("| case | contact whisker-frames | with a load | M0 within ±2 SD | force within ±2 SD "
          "| median abs z (M0) | median rel. error (M0) | median SD / truth (M0) "
          "| m0 within ±2 SD | frames without contact | |m0| ≤ 3 SD there |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['case']} | {r['contact_whisker_frames']} | {r['with_load']} "
              f"| {r['moment_within_2sd']:.2f} | {r['force_within_2sd']:.2f} "
              f"| {r['moment_median_abs_z']:.2f} | {r['moment_median_rel_error']:.2f} "
              f"| {r['moment_median_rel_sd']:.3f} | {r['m0_within_2sd']:.2f} "
              f"| {r['quiet_frames']} | {r['quiet_m0_within_3sd']:.3f} |")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()

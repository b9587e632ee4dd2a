#!/usr/bin/env python3
"""Scores sinew-track --whiskers results against sinew-synth --scenario whisker-pad's truth.

Identities: each whisker found on the first frame is matched to the true whisker its curve lies
nearest (mean distance of its samples to the true centreline; one true whisker per id). Then per
whisker-frame:
- curve distance: the mean distance of the tracked curve's samples (every pixel along its nodes'
  chords) to the true centreline polyline;
- base distance: tracked follicle (first node) to the true follicle;
- a swap: the tracked curve lies nearer (by mean distance) another true whisker than its own;
- good: status "ok" and curve distance <= --max-curve-px.

With a contact load in the results (contact_moment_model, contact_force_model), its errors
against the truth's contact force and that force's moment about the true follicle.

Prints the figures and exits 1 when any of --require-found, --require-good, --max-base-px,
--max-contact-arc-px, --max-contact-moment-error, --max-follicle-force-error or the no-swap
rule fails (so a test can call it).
"""
import argparse
import json
import sys

import numpy as np


def samples(nodes, step=1.0):
    pts = np.asarray(nodes, dtype=float)[:, :2]
    seg = np.diff(pts, axis=0)
    lengths = np.hypot(seg[:, 0], seg[:, 1])
    s = np.concatenate([[0.0], np.cumsum(lengths)])
    t = np.arange(0.0, s[-1] + 1e-9, step)
    idx = np.clip(np.searchsorted(s, t, side="right") - 1, 0, len(seg) - 1)
    frac = (t - s[idx]) / np.maximum(lengths[idx], 1e-12)
    return pts[idx] + seg[idx] * frac[:, None]


def distance_to_polyline(points, poly):
    """Distance of each point to the polyline poly (n x 2)."""
    a = poly[:-1][None, :, :]
    b = poly[1:][None, :, :]
    p = points[:, None, :]
    ab = b - a
    t = np.clip(np.sum((p - a) * ab, axis=2) / np.maximum(np.sum(ab * ab, axis=2), 1e-12), 0, 1)
    closest = a + t[:, :, None] * ab
    return np.min(np.linalg.norm(p - closest, axis=2), axis=1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--results", required=True)
    ap.add_argument("--truth", required=True)
    ap.add_argument("--max-curve-px", type=float, default=0.5)
    ap.add_argument("--min-length-px", type=float, default=40.0)
    ap.add_argument("--require-found", action="store_true",
                    help="every true whisker longer than --min-length-px found on frame 0")
    ap.add_argument("--max-contact-arc-px", type=float, default=None,
                    help="require every true contact frame reported touching (but for one frame "
                         "at each onset and offset), no touch reported more than one frame from a "
                         "true one, and the median contact point within this arc length")
    ap.add_argument("--max-contact-moment-error", type=float, default=None,
                    help="require the median relative error of the contact's moment about the "
                         "follicle (sinew-track's contact load) at most this")
    ap.add_argument("--max-follicle-force-error", type=float, default=None,
                    help="require the median error of the force on the follicle (axial, lateral) "
                         "at most this fraction of the true force")
    ap.add_argument("--require-good", type=float, default=0.0,
                    help="fraction of whisker-frames that must be good")
    ap.add_argument("--max-base-px", type=float, default=float("inf"),
                    help="largest allowed median base distance of a whisker")
    args = ap.parse_args()

    truth = {}
    for line in open(args.truth):
        rec = json.loads(line)
        truth[rec["frame"]] = {w["id"]: w for w in rec["whiskers"]}
    results = []
    for line in open(args.results):
        rec = json.loads(line)
        if "frame" in rec:
            results.append(rec)
    if not results:
        sys.exit("no frames in " + args.results)

    first = results[0]
    t0 = truth[first["frame"]]
    polys = {k: np.asarray(w["centreline"], dtype=float) for k, w in t0.items()}
    # Identity match on the first frame (greedy on mean distance).
    pairs = []
    for w in first["whiskers"]:
        pts = samples(w["nodes"])
        for k, poly in polys.items():
            pairs.append((float(np.mean(distance_to_polyline(pts, poly))), w["id"], k))
    pairs.sort()
    match, used = {}, set()
    for d, wid, k in pairs:
        if wid in match or k in used or d > 2.0:
            continue
        match[wid] = k
        used.add(k)
    long_truth = [k for k, w in t0.items() if w["length_px"] > args.min_length_px]
    found = [k for k in long_truth if k in used]
    print(f"frame {first['frame']}: {len(first['whiskers'])} whiskers reported, "
          f"{len(found)} of {len(long_truth)} true whiskers longer than {args.min_length_px:g} px "
          f"found; {len(first['whiskers']) - len(match)} reported whiskers match none")

    total = good = swaps = ok = 0
    # Contact, per matched whisker: frames reported touching / truly touching, arc errors.
    said, true_contact, arc_errors = {}, {}, []
    # The contact load against the truth's: the contact's moment about the follicle and the force.
    moment_errors, force_errors, pammer_errors = [], [], []
    # (whisker, |moment error|, true moment) per contact frame: the same errors in units of the
    # whisker's largest true contact moment (at an onset the true moment tends to 0 and a relative
    # error to infinity, whatever the estimate).
    moment_pairs = []
    # The force on the follicle in the base frame (axial, lateral) against the truth's: the
    # contact force in the true whisker's base frame; error relative to the true force's size.
    follicle_errors = []
    no_load = 0  # contact frames whose load fit found no load (counted as 100 % off)
    curve, base, per_curve = [], {}, {}
    worst_swap = None
    for rec in results:
        tf = truth[rec["frame"]]
        tpolys = {k: np.asarray(w["centreline"], dtype=float) for k, w in tf.items()}
        for w in rec["whiskers"]:
            if w["id"] not in match:
                continue
            k = match[w["id"]]
            total += 1
            pts = samples(w["nodes"])
            d_own = float(np.mean(distance_to_polyline(pts, tpolys[k])))
            if "contact" in w:
                tc = tf[k].get("contact")
                if w["contact"]:
                    said.setdefault(k, set()).add(rec["frame"])
                if tc:
                    true_contact.setdefault(k, set()).add(rec["frame"])
                if w["contact"] and tc:
                    arc_errors.append(abs(w["contact_arc_length_px"] - tc["arc_length_px"]))
                if w.get("contact") and tc and "contact_moment_model" in w:
                    force = np.asarray(tc["force"], dtype=float)
                    arm = np.asarray(tc["point"], dtype=float) - tf[k]["follicle"]
                    true_moment = arm[0] * force[1] - arm[1] * force[0]
                    if w["contact_moment_model"] is None:
                        # No load found (the fit found no equilibrium): the whole load missed.
                        no_load += 1
                        moment_errors.append(1.0)
                        force_errors.append(1.0)
                        moment_pairs.append((k, abs(true_moment), true_moment))
                    else:
                        moment_pairs.append((k, abs(w["contact_moment_model"] - true_moment),
                                             true_moment))
                        moment_errors.append(abs(w["contact_moment_model"] - true_moment)
                                             / abs(true_moment))
                        force_errors.append(float(np.linalg.norm(
                            np.asarray(w["contact_force_model"]) - force)
                            / np.linalg.norm(force)))
                    if w.get("follicle_force_axial_model") is not None:
                        c = np.asarray(tf[k]["centreline"], dtype=float)
                        t0 = c[1] - c[0]
                        t0 /= np.linalg.norm(t0)
                        true_follicle = np.array([-force @ t0,
                                                  force[1] * t0[0] - force[0] * t0[1]])
                        got = np.array([w["follicle_force_axial_model"],
                                        w["follicle_force_lateral_model"]])
                        follicle_errors.append(float(np.linalg.norm(got - true_follicle)
                                                     / np.linalg.norm(force)))
                    elif w["contact_moment_model"] is None:
                        follicle_errors.append(1.0)
                    if "pammer_moment_model" in w:
                        pammer_errors.append(abs(w["pammer_moment_model"] - true_moment)
                                             / abs(true_moment))
            if w["status"] == "ok":
                ok += 1
                curve.append(d_own)
                per_curve.setdefault(w["id"], []).append(d_own)
                base.setdefault(w["id"], []).append(
                    float(np.hypot(*(np.asarray(w["follicle"]) - tf[k]["follicle"]))))
                good += d_own <= args.max_curve_px
                others = [float(np.mean(distance_to_polyline(pts, p)))
                          for j, p in tpolys.items() if j != k]
                if others and min(others) < d_own:
                    swaps += 1
                    worst_swap = worst_swap or (rec["frame"], w["id"])
    missed = [k for k in truth[first["frame"]] if k not in used]
    for k in missed:  # a true whisker never found counts as bad on every frame
        total += len(results)
    frac_good = good / max(total, 1)
    base_medians = {i: float(np.median(v)) for i, v in base.items()}
    print(f"whisker-frames of true whiskers: {total}; ok {ok}; good (ok and within "
          f"{args.max_curve_px} px) {good} = {100 * frac_good:.1f}%")
    if curve:
        print(f"curve distance of ok frames: mean {np.mean(curve):.3f} px, "
              f"median {np.median(curve):.3f}, p95 {np.percentile(curve, 95):.3f}, "
              f"max {np.max(curve):.3f}")
    if per_curve:
        print("curve distance per whisker, mean px (true id): " +
              ", ".join(f"{i} ({match[i]}): {np.mean(v):.2f}" for i, v in sorted(per_curve.items())))
    if per_curve:
        print("frames beyond " + f"{args.max_curve_px} px per whisker: " +
              ", ".join(f"{i}: {sum(d > args.max_curve_px for d in v)}"
                        for i, v in sorted(per_curve.items())))
    if base_medians:
        print("base distance per whisker, median px: " +
              ", ".join(f"{i}: {v:.2f}" for i, v in sorted(base_medians.items())))
    print(f"identity swaps: {swaps}" + (f" (first: frame {worst_swap[0]}, id {worst_swap[1]})"
                                        if worst_swap else ""))
    # A touch reported within one frame of a true one is onset/offset timing, not a false contact.
    missed_c = spurious_c = edge = 0
    for k in set(said) | set(true_contact):
        t, r = true_contact.get(k, set()), said.get(k, set())
        near = {f + d for f in t for d in (-1, 0, 1)}
        spurious_c += len(r - near)
        for f in t - r:
            if (f - 1 in t) and (f + 1 in t):
                missed_c += 1  # inside a contact interval
            else:
                edge += 1
    if true_contact or said:
        print(f"contact: {sum(len(v) for v in true_contact.values())} true whisker-frames, "
              f"{sum(len(v) for v in said.values())} reported; missed inside an interval "
              f"{missed_c}, at an onset/offset {edge}; reported > 1 frame from a true contact "
              f"{spurious_c}; contact point error along the whisker median "
              f"{np.median(arc_errors) if arc_errors else float('nan'):.2f} px, max "
              f"{max(arc_errors) if arc_errors else float('nan'):.2f} px")
    if moment_errors:
        me, fe = np.asarray(moment_errors), np.asarray(force_errors)
        print(f"contact load (frames in contact after the rest frame, {len(me)}): moment about "
              f"the follicle error median {100 * np.median(me):.1f} %, 90th percentile "
              f"{100 * np.percentile(me, 90):.1f} %, within 5 % on {int((me <= 0.05).sum())}; "
              f"force error median {100 * np.median(fe):.1f} %, within 10 % on "
              f"{int((fe <= 0.10).sum())}; no load found on {no_load} (counted as 100 % off)")
        peak = {}
        for k, _, t in moment_pairs:
            peak[k] = max(peak.get(k, 0.0), abs(t))
        of_peak = np.asarray([d / peak[k] for k, d, _ in moment_pairs])
        large = [(d, t) for k, d, t in moment_pairs if abs(t) >= 0.25 * peak[k]]
        rel_large = np.asarray([d / abs(t) for d, t in large])
        print(f"  the moment error in units of the whisker's largest true contact moment: median "
              f"{100 * np.median(of_peak):.1f} %, 90th percentile "
              f"{100 * np.percentile(of_peak, 90):.1f} %, within 5 % on "
              f"{int((of_peak <= 0.05).sum())}; on the {len(large)} frames whose moment is at "
              f"least a quarter of it, relative error median "
              f"{100 * np.median(rel_large) if large else float('nan'):.1f} %, within 5 % on "
              f"{int((rel_large <= 0.05).sum())}")
        if pammer_errors:
            pe = np.asarray(pammer_errors)
            print(f"  beside it, the quasi-static (Pammer) moment from the curvature change: error "
                  f"median {100 * np.median(pe):.1f} %, 90th percentile "
                  f"{100 * np.percentile(pe, 90):.1f} %, within 5 % on {int((pe <= 0.05).sum())}")
    if follicle_errors:
        fo = np.asarray(follicle_errors)
        print(f"  force on the follicle (axial, lateral in the base frame) against the truth's: "
              f"error median {100 * np.median(fo):.1f} % of the force, 90th percentile "
              f"{100 * np.percentile(fo, 90):.1f} %, within 10 % on {int((fo <= 0.10).sum())} "
              f"of {len(fo)}")
    failed = []
    if args.max_follicle_force_error is not None:
        if not follicle_errors or np.median(follicle_errors) > args.max_follicle_force_error:
            failed.append("follicle force error")
    if args.max_contact_moment_error is not None:
        if not moment_errors or np.median(moment_errors) > args.max_contact_moment_error:
            failed.append("contact moment error")
    if args.max_contact_arc_px is not None:
        if missed_c or spurious_c:
            failed.append(f"contact: {missed_c} missed, {spurious_c} spurious")
        if not arc_errors or np.median(arc_errors) > args.max_contact_arc_px:
            failed.append("contact point error")
    if args.require_found and len(found) < len(long_truth):
        failed.append("not every whisker found")
    if frac_good < args.require_good:
        failed.append(f"good {100 * frac_good:.1f}% < {100 * args.require_good:.1f}%")
    if swaps:
        failed.append("identity swaps")
    if base_medians and max(base_medians.values()) > args.max_base_px:
        failed.append(f"base distance {max(base_medians.values()):.2f} px > {args.max_base_px}")
    if failed:
        print("FAILED: " + "; ".join(failed))
        sys.exit(1)


if __name__ == "__main__":
    main()

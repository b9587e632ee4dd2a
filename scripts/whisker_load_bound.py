#!/usr/bin/env python3
"""How precisely can any tracker read a rendered whisker's contact load from one noisy frame?

A lower bound, frame by frame, for sinew-synth --scenario whisker-pad's truth (truth.jsonl): the
Cramer-Rao bound on the relative error of the contact force's magnitude, and with it of the
moment about the follicle (their ratio, the lever arm, is taken as known). Written apart from the
tracker (numpy only) so that it says what the images allow, not what one method reaches.

The model; every simplification gives the estimator more than the frame holds, so the bound is
lower, never higher, than the true one:
- The frame is the synth's: the whisker's darkening (draw() copies tools/synth/whisker_pad.cpp's
  draw_whisker) plus white Gaussian noise of sigma grey levels. Ignored, each of which would only
  lose information: 8-bit rounding and saturation, and the floor that keeps a whisker over the
  face or the pole from darkening them fully.
- The load's effect on the shape is the truth's own deflection: the frame's centreline minus the
  rest frame's, turned by the frame's base angle about its follicle (exactly zero on every free
  frame). To first order a load (1 + e) times the true one moves each node by e times it.
- Given to the estimator for free: the rest shape, the contact point, the contrast, the backlight
  and the follicle's position. Unknown: the load's size and the turn about the follicle (the
  whisking the load must be told apart from).
- Information: J = C^T C / sigma^2, C the drawing's change per unit step of each parameter (finite
  differences of 5e-4: linear, as tests/python/test_whisker_load_bound.py checks). This counts
  everything the drawn frame holds, the ends included (its tip ends abruptly at 40 % contrast and
  its first pixels lie on the face's edge); continuous_information() counts only the sides along
  the length (2 c(s)^2 / sigma^2 per px), as a real whisker's fading tip and furred follicle would
  leave it, and gives a higher bound.
The bound on the load's relative standard deviation is sqrt((J^-1)_FF) over (load, turn). A load
that differs by the factor 1.05/0.95 (the closest pair an estimator within 5 % of every truth must
tell apart) changes the image by d' = 0.105 sqrt(J_FF - J_Ft^2 / J_tt) noise units after the best
compensating turn; any estimator, biased or not, is then more than 5 % off on at least one of the
two with probability Phi(-d'/2) or more. Also per frame: the bound when the follicle's position
across the whisker is unknown too (a tracker reads it from the whisker itself; the face's edge
fixes it only along the whisker).

The shared whisker_pad renderer's sequences (--shared-truth truth.json): the same bound with its own
drawing (its render.py's raster_whisker and 0.5 px blur, imported from --renderer at run time),
every whisker in contact, the rest the first free frame, σ its truth's noise; with --results,
sinew-track's contact moment against issue 49's bar (within max(5 %, 2 x that frame's bound)).

Prints one line per contact frame (with --results, the tracker's own error beside it) and a
summary: on how many contact frames the bound's standard deviation alone exceeds 5 % (moment)
and 10 % (force).
"""
import argparse
import json
import math
import os
import sys

import numpy as np


def arc_lengths(points):
    seg = np.diff(points, axis=0)
    return np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])


def resample(points, s_new):
    s = arc_lengths(points)
    return np.column_stack([np.interp(s_new, s, points[:, 0]), np.interp(s_new, s, points[:, 1])])


def rotation(deg):
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def draw(curve, contrast, box):
    """The synth's whisker (tools/synth/whisker_pad.cpp, draw_whisker): its darkening, grey levels,
    over the pixels of box = (x0, y0, x1, y1): each chord sampled every <= 0.25 px, each sample
    darkening the pixels within its half width (1.5 -> 0.5 px, anti-aliased) by its contrast
    (falling to 40 % at the tip), the darkest sample winning."""
    s_nodes = arc_lengths(curve)
    length = s_nodes[-1]
    p, s = [], []
    for i in range(len(curve) - 1):
        seg = s_nodes[i + 1] - s_nodes[i]
        steps = max(1, int(np.ceil(seg / 0.25)))
        t = np.arange(steps + 1) / steps
        p.append(curve[i] + t[:, None] * (curve[i + 1] - curve[i]))
        s.append(s_nodes[i] + t * seg)
    p, s = np.vstack(p), np.concatenate(s)
    half = 0.5 * (3.0 - 2.0 * s / length)
    c = contrast * (1.0 - 0.6 * s / length)
    x, y = np.meshgrid(np.arange(box[0], box[2]), np.arange(box[1], box[3]))
    dark = np.zeros(x.shape)
    for i in range(len(s)):
        cover = np.clip(half[i] + 0.5 - np.hypot(x - p[i, 0], y - p[i, 1]), 0.0, 1.0)
        dark = np.maximum(dark, c[i] * cover)
    return dark


def box_of(points, margin=5):
    return (int(points[:, 0].min()) - margin, int(points[:, 1].min()) - margin,
            int(points[:, 0].max()) + margin + 1, int(points[:, 1].max()) + margin + 1)


def directions(curve, deflection):
    """Each node's displacement per unit of (relative load, turn about the follicle in radians,
    shift of the follicle across the whisker in px)."""
    t0 = (curve[1] - curve[0]) / np.linalg.norm(curve[1] - curve[0])
    n0 = np.array([-t0[1], t0[0]])
    arm = curve - curve[0]
    turn = np.column_stack([-arm[:, 1], arm[:, 0]])
    return [deflection, turn, np.tile(n0, (len(curve), 1))]


def information(curve, deflection, contrast, sigma, e=5e-4, drawer=None):
    """J (3 x 3) for (relative load, turn, the follicle's shift across the whisker) of one frame, from
    the drawing itself: the image change of a small step e in each, in units of the noise. Exact
    for the synth's frames (ends, pixel grid and all) to first order. curve: the frame's
    centreline (n x 2, follicle first); deflection: the load's displacement of each node.
    drawer(curve, box): another renderer's darkening (default: the synth's draw())."""
    if drawer is None:
        drawer = lambda c, box: draw(c, contrast, box)  # noqa: E731
    moved = [curve + e * d for d in directions(curve, deflection)]
    box = box_of(np.vstack([curve] + moved))
    base = drawer(curve, box)
    columns = np.column_stack([(drawer(m, box) - base).ravel() / e for m in moved])
    return columns.T @ columns / (sigma * sigma)


def shared_drawer(renderer_dir):
    """The shared whisker_pad renderer's own drawing (its render.py's raster_whisker, imported from
    renderer_dir, not copied), then its 0.5 px Gaussian blur: a whisker's darkening, grey levels,
    over the box. The curve is its 41 truth nodes (the whole whisker, tip included), resampled every
    0.5 px as the renderer draws it."""
    sys.path.insert(0, renderer_dir)
    import cv2
    import render  # noqa: E402  (../shared/tools/whisker_pad/render.py)

    def drawer(curve, box):
        s_nodes = arc_lengths(curve)
        s = np.linspace(0.0, s_nodes[-1], max(2, int(np.ceil(s_nodes[-1] / 0.5)) + 1))
        dense = resample(curve, s)
        img = np.full((render.H, render.W), 200.0)
        render.raster_whisker(img, np.full_like(img, 200.0), dense, s, s_nodes[-1])
        img = cv2.GaussianBlur(img, (0, 0), 0.5)
        x0, y0, x1, y1 = box
        return (200.0 - img)[max(y0, 0):y1, max(x0, 0):x1]
    return drawer


def shared_sequences(truth_path):
    """The shared renderer's truth.json as this script's per-whisker frame lists: for every whisker
    with contact frames, one dict per frame with its centreline, base angle, follicle, contact
    (point and force vector) and the true M0 (N m, the renderer's sign). Also its noise sigma."""
    truth = json.load(open(truth_path))
    ids = sorted({w["id"] for f in truth["frames"] for w in f["whiskers"] if w["contact"]})
    sequences = {}
    for wid in ids:
        seq = []
        for f in truth["frames"]:
            w = next(x for x in f["whiskers"] if x["id"] == wid)
            seq.append({"centreline": w["nodes"], "base_angle_deg": w["base_angle_deg"],
                        "follicle": w["follicle"], "M0_Nm": w["M0_Nm"],
                        "contact": ({"point": w["contact_point_px"],
                                     "force": w["contact_force_vec_N"]} if w["contact"] else None)})
        sequences[wid] = seq
    return sequences, float(truth.get("noise_sigma", 4.0))


def continuous_information(curve, deflection, contrast, sigma, step=0.25):
    """The same J from a continuous model: moving the centreline by delta along its normal at arc
    length s changes its two 1-px edge ramps by c(s) delta each, 2 c(s)^2 / sigma^2 of information
    per px of length, and nothing else (no ends). A check on the drawn one."""
    s_nodes = arc_lengths(curve)
    length = s_nodes[-1]
    s = np.arange(0.0, length + 1e-9, step)
    p = resample(curve, s)
    t = np.gradient(p, s, axis=0)
    t /= np.linalg.norm(t, axis=1)[:, None]
    n = np.column_stack([-t[:, 1], t[:, 0]])
    rows = []
    for d in directions(curve, deflection):
        di = np.column_stack([np.interp(s, s_nodes, d[:, 0]), np.interp(s, s_nodes, d[:, 1])])
        rows.append(np.sum(di * n, axis=1))
    v = np.vstack(rows)
    c = contrast * (1.0 - 0.6 * s / length)
    density = 2.0 * c * c / (sigma * sigma) * step
    return (v * density) @ v.T


def normal_deflection(curve, deflection):
    t = np.gradient(curve, axis=0)
    t /= np.linalg.norm(t, axis=1)[:, None]
    return np.sum(deflection * np.column_stack([-t[:, 1], t[:, 0]]), axis=1)


def bound_from_information(J):
    """(relative standard deviation bound, d' of a 1.05/0.95 load ratio after the best turn)."""
    effective = J[0, 0] - J[0, 1] ** 2 / J[1, 1]
    if effective <= 0.0:
        return math.inf, 0.0
    return 1.0 / math.sqrt(effective), (1.05 / 0.95 - 1.0) * math.sqrt(effective)


def bound_with_follicle_free(J):
    """The bound on the load's relative sd when the follicle's position across the whisker is
    unknown too."""
    return math.sqrt(np.linalg.inv(J)[0, 0])


def phi(x):
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


def shared_main(args):
    """The bound per contact frame of the shared renderer's sequence, each whisker in contact, and
    with --results sinew-track's contact moment against it (issue 49's acceptance: within
    max(5 %, 2 x that frame's bound), medians within 2 x the median bound)."""
    sequences, sigma = shared_sequences(args.shared_truth)
    if args.sigma_given:
        sigma = args.sigma
    drawer = shared_drawer(args.renderer)
    results = {}
    if args.results:
        for line in open(args.results):
            r = json.loads(line)
            if "frame" in r:
                results[r["frame"]] = [w for w in r["whiskers"] if w.get("status", "ok") == "ok"]
    summary = []
    for wid, seq in sequences.items():
        rest_k = args.rest_frame if args.rest_frame is not None else next(
            k for k, w in enumerate(seq) if not w["contact"])
        rest = seq[rest_k]
        if rest["contact"]:
            sys.exit(f"whisker {wid}: rest frame {rest_k} is a contact frame")
        rest_curve = np.asarray(rest["centreline"], float)
        rest_local = (rest_curve - rest_curve[0]) @ rotation(rest["base_angle_deg"])
        print(f"whisker {wid} (rest frame {rest_k}, sigma {sigma})")
        print("frame  |M0|/peak  bound sd %  d'(1.05/0.95)  tracker %")
        peak = max(abs(w["M0_Nm"]) for w in seq if w["contact"])
        for k, w in enumerate(seq):
            if not w["contact"] or k == rest_k:
                continue
            curve = np.asarray(w["centreline"], float)
            free = curve[0] + rest_local @ rotation(w["base_angle_deg"]).T
            sd, dprime = bound_from_information(
                information(curve, curve - free, None, sigma, drawer=drawer))
            error = None
            best, best_d = None, 3.0
            for t in results.get(k, []):
                nodes = np.asarray(t["nodes"], float)[:, :2]
                d = float(np.mean(np.min(np.linalg.norm(nodes[:, None, :] - curve[None], axis=2),
                                         axis=1)))
                if d < best_d:
                    best, best_d = t, d
            if best is not None and best.get("contact_moment_N_m") is not None and w["M0_Nm"]:
                # Sinew's moment is (x_c - x_0) x F in image axes; the renderer's M0 its negative.
                error = (-best["contact_moment_N_m"] - w["M0_Nm"]) / abs(w["M0_Nm"])
            print(f"{k:5d}  {abs(w['M0_Nm']) / peak:8.3f}  {100 * sd:10.2f}  {dprime:13.2f}  "
                  + ("    –" if error is None else f"{100 * error:+8.1f}"))
            summary.append((wid, k, sd, error))
    if not summary:
        sys.exit("no contact frame")
    sds = np.array([r[2] for r in summary])
    print(f"contact whisker-frames: {len(summary)}; bound on the load's relative sd: median "
          f"{100 * np.median(sds):.2f} %, above 5 % on {int(np.sum(sds > 0.05))}, above 10 % on "
          f"{int(np.sum(sds > 0.10))}")
    if results:
        within = sum(1 for r in summary
                     if r[3] is not None and abs(r[3]) <= max(0.05, 2.0 * r[2]))
        errors = [abs(r[3]) for r in summary if r[3] is not None]
        print(f"tracker: within max(5 %, 2 x bound) on {within} of {len(summary)} "
              f"({100.0 * within / len(summary):.0f} %; a frame without a load counts as missed); "
              f"error median {100 * np.median(errors) if errors else math.nan:.1f} % on the "
              f"{len(errors)} with a load, against 2 x the median bound "
              f"{200 * np.median(sds):.2f} %")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--truth", help="sinew-synth's truth.jsonl")
    ap.add_argument("--shared-truth",
                    help="the shared whisker_pad renderer's truth.json instead (its drawing is "
                         "imported from --renderer)")
    ap.add_argument("--renderer", default=os.path.join(
        os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "tools", "whisker_pad"),
                    help="the shared renderer's folder (default ../shared/tools/whisker_pad)")
    ap.add_argument("--rest-frame", type=int, default=None,
                    help="default 30 (sinew-synth), the first free frame (shared renderer)")
    ap.add_argument("--sigma", type=float, default=None,
                    help="image noise, grey levels (default 4, or the shared truth's)")
    ap.add_argument("--whisker", type=int, default=None,
                    help="true whisker id (default: the one with contact frames)")
    ap.add_argument("--results", help="sinew-track's results: print its moment error beside")
    args = ap.parse_args()
    args.sigma_given = args.sigma is not None
    if args.shared_truth:
        return shared_main(args)
    if not args.truth:
        ap.error("give --truth or --shared-truth")
    if args.rest_frame is None:
        args.rest_frame = 30
    if args.sigma is None:
        args.sigma = 4.0

    frames = [json.loads(line) for line in open(args.truth)]
    wid = args.whisker
    if wid is None:
        wid = next(w["id"] for f in frames for w in f["whiskers"] if w.get("contact"))
    byid = [{w["id"]: w for w in f["whiskers"]}[wid] for f in frames]
    rest = byid[args.rest_frame]
    if rest.get("contact"):
        sys.exit(f"rest frame {args.rest_frame} is a contact frame")
    rest_curve = np.asarray(rest["centreline"], float)
    rest_local = (rest_curve - rest_curve[0]) @ rotation(rest["base_angle_deg"])  # R^T applied

    tracked = {}
    if args.results:
        for line in open(args.results):
            r = json.loads(line)
            for w in r.get("whiskers", []):
                if w.get("contact_moment_model") is not None:
                    tracked[r["frame"]] = w["contact_moment_model"]

    peak = max(abs(np.cross(np.asarray(w["contact"]["point"]) - np.asarray(w["follicle"]),
                            np.asarray(w["contact"]["force"])))
               for w in byid if w.get("contact"))
    rows = []
    print("frame  |M|/peak  max|w| px  bound sd %  d'(1.05/0.95)  P(>5% off) >=  "
          "sd, follicle across free %" + ("  tracker %" if tracked else ""))
    for k, w in enumerate(byid):
        if k <= args.rest_frame or not w.get("contact"):
            continue
        curve = np.asarray(w["centreline"], float)
        free = curve[0] + rest_local @ rotation(w["base_angle_deg"]).T
        if len(free) != len(curve):
            sys.exit(f"frame {k}: {len(curve)} nodes, rest frame {len(free)}")
        J = information(curve, curve - free, w["contrast"], args.sigma)
        wn = normal_deflection(curve, curve - free)
        sd, dprime = bound_from_information(J)
        sd_free = bound_with_follicle_free(J)
        lever = np.asarray(w["contact"]["point"]) - np.asarray(w["follicle"])
        moment = float(np.cross(lever, np.asarray(w["contact"]["force"])))
        line = (f"{k:5d}  {abs(moment) / peak:7.3f}  {np.max(np.abs(wn)):9.3f}  "
                f"{100 * sd:10.2f}  {dprime:13.2f}  {phi(-dprime / 2):13.2f}  "
                f"{100 * sd_free:26.2f}")
        error = None
        if k in tracked:
            error = (tracked[k] - moment) / abs(moment)
            line += f"  {100 * error:+9.1f}"
        print(line)
        rows.append((k, abs(moment) / peak, sd, dprime, error, sd_free))
    if not rows:
        sys.exit("no contact frame after the rest frame")
    sds = np.array([r[2] for r in rows])
    print(f"contact frames after rest frame {args.rest_frame}: {len(rows)}; bound on the load's "
          f"relative sd: median {100 * np.median(sds):.2f} %, max {100 * np.max(sds):.1f} %; "
          f"frames where it exceeds 5 %: {int(np.sum(sds > 0.05))}, 10 %: "
          f"{int(np.sum(sds > 0.10))}")
    print(f"the follicle's position across the whisker: with it unknown too the bound is "
          f"{100 * np.median([r[5] for r in rows]):.2f} % (median; above 5 % on "
          f"{sum(r[5] > 0.05 for r in rows)} frames)")
    if tracked:
        allowed = [r for r in rows if r[2] <= 0.025 and r[4] is not None]
        within = sum(abs(r[4]) <= 0.05 for r in allowed)
        errors = np.abs([r[4] for r in allowed])
        print(f"tracker on the {len(allowed)} frames where the bound's sd is at most 2.5 % (a 5 % "
              f"reading is 2 sd): within 5 % on {within}, error median {100 * np.median(errors):.1f} "
              f"%, largest {100 * np.max(errors):.1f} %")


if __name__ == "__main__":
    main()

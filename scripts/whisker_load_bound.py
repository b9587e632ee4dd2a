#!/usr/bin/env python3
"""How precisely can any tracker read a rendered whisker's contact load from one noisy frame?

A lower bound, frame by frame, for sinew-synth --scenario whisker-pad's truth (truth.jsonl): the
Cramer-Rao bound on the relative error of the contact force's magnitude, and with it of the
moment about the follicle (their ratio, the lever arm, is taken as known). Written apart from the
tracker (numpy only) so that it says what the images allow, not what one method reaches.

The model, and every simplification makes the bound lower, never higher:
- The frame is the rendered one: a whisker darkening its pixels by c(s) = contrast (1 - 0.6 s/L)
  over its width with 1-px anti-aliased edges (tools/synth/whisker_pad.cpp), plus white Gaussian
  noise of sigma grey levels. Moving the centreline by delta along its normal at arc length s
  changes the two edge ramps by c(s) delta each, so each pixel of length carries Fisher information
  2 c(s)^2 / sigma^2 about the normal displacement there.
- The load's effect on the shape is the truth's own deflection: the frame's centreline minus the
  rest frame's, turned by the frame's base angle about its follicle (w(s), along the normal). To
  first order a load (1 + e) times the true one moves the centreline by e w(s).
- Known exactly (given to the estimator for free): the follicle's position, the rest shape, the
  contact point, the contrast, the backlight. Unknown: the load's size and the base angle (the
  whisking the load must be told apart from: a turn moves the curve by t(s).(p(s) - p0) along the
  normal).
So the bound on the load's relative standard deviation is sqrt((J^-1)_FF) with
J = sum over the curve of 2 c^2 / sigma^2 [w, r][w, r]^T ds. A load that differs by the factor
1.05/0.95 (the closest pair an estimator within 5 % of every truth must tell apart) changes the
image by d' = 0.105 sqrt(J_FF - J_Fr^2 / J_rr) noise units after the best compensating turn; any
estimator, biased or not, is then more than 5 % off on at least one of the two with probability
Phi(-d'/2) or more.

Prints one line per contact frame (with --results, the tracker's own error beside it) and a
summary: on how many contact frames the bound's standard deviation alone exceeds 5 % (moment)
and 10 % (force).
"""
import argparse
import json
import math
import sys

import numpy as np


def resample(points, s_new):
    seg = np.diff(points, axis=0)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])
    return np.column_stack([np.interp(s_new, s, points[:, 0]), np.interp(s_new, s, points[:, 1])])


def arc_lengths(points):
    seg = np.diff(points, axis=0)
    return np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])


def rotation(deg):
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def information(curve, deflection, contrast, sigma, step=0.25):
    """J (2 x 2) for (relative load, base angle) of one frame. curve: the frame's centreline (n x 2,
    follicle first); deflection: the load's displacement of each node (n x 2)."""
    s_nodes = arc_lengths(curve)
    length = s_nodes[-1]
    s = np.arange(0.0, length + 1e-9, step)
    p = resample(curve, s)
    d = np.column_stack([np.interp(s, s_nodes, deflection[:, 0]),
                         np.interp(s, s_nodes, deflection[:, 1])])
    t = np.gradient(p, s, axis=0)
    t /= np.linalg.norm(t, axis=1)[:, None]
    n = np.column_stack([-t[:, 1], t[:, 0]])
    w = np.sum(d * n, axis=1)                   # normal displacement per unit relative load
    r = np.sum(t * (p - p[0]), axis=1)          # normal displacement per radian of base turn
    c = contrast * (1.0 - 0.6 * s / length)
    density = 2.0 * c * c / (sigma * sigma) * step
    v = np.vstack([w, r])
    return (v * density) @ v.T, w


def bound_from_information(J):
    """(relative standard deviation bound, d' of a 1.05/0.95 load ratio after the best turn)."""
    effective = J[0, 0] - J[0, 1] ** 2 / J[1, 1]
    if effective <= 0.0:
        return math.inf, 0.0
    return 1.0 / math.sqrt(effective), (1.05 / 0.95 - 1.0) * math.sqrt(effective)


def phi(x):
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--truth", required=True)
    ap.add_argument("--rest-frame", type=int, default=30)
    ap.add_argument("--sigma", type=float, default=4.0, help="image noise, grey levels")
    ap.add_argument("--whisker", type=int, default=None,
                    help="true whisker id (default: the one with contact frames)")
    ap.add_argument("--results", help="sinew-track's results: print its moment error beside")
    args = ap.parse_args()

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
    print("frame  |M|/peak  max|w| px  bound sd %  d'(1.05/0.95)  P(>5% off) >=" +
          ("  tracker %" if tracked else ""))
    for k, w in enumerate(byid):
        if k <= args.rest_frame or not w.get("contact"):
            continue
        curve = np.asarray(w["centreline"], float)
        free = curve[0] + rest_local @ rotation(w["base_angle_deg"]).T
        if len(free) != len(curve):
            sys.exit(f"frame {k}: {len(curve)} nodes, rest frame {len(free)}")
        J, wn = information(curve, curve - free, w["contrast"], args.sigma)
        sd, dprime = bound_from_information(J)
        lever = np.asarray(w["contact"]["point"]) - np.asarray(w["follicle"])
        moment = float(np.cross(lever, np.asarray(w["contact"]["force"])))
        line = (f"{k:5d}  {abs(moment) / peak:7.3f}  {np.max(np.abs(wn)):9.3f}  "
                f"{100 * sd:10.2f}  {dprime:13.2f}  {phi(-dprime / 2):13.2f}")
        error = None
        if k in tracked:
            error = (tracked[k] - moment) / abs(moment)
            line += f"  {100 * error:+9.1f}"
        print(line)
        rows.append((k, abs(moment) / peak, sd, dprime, error))
    if not rows:
        sys.exit("no contact frame after the rest frame")
    sds = np.array([r[2] for r in rows])
    print(f"contact frames after rest frame {args.rest_frame}: {len(rows)}; bound on the load's "
          f"relative sd: median {100 * np.median(sds):.2f} %, max {100 * np.max(sds):.1f} %; "
          f"frames where it exceeds 5 %: {int(np.sum(sds > 0.05))}, 10 %: "
          f"{int(np.sum(sds > 0.10))}")
    if tracked:
        allowed = [r for r in rows if r[2] <= 0.025 and r[4] is not None]
        within = sum(abs(r[4]) <= 0.05 for r in allowed)
        errors = np.abs([r[4] for r in allowed])
        print(f"tracker on the {len(allowed)} frames where the bound's sd is at most 2.5 % (a 5 % "
              f"reading is 2 sd): within 5 % on {within}, error median {100 * np.median(errors):.1f} "
              f"%, largest {100 * np.max(errors):.1f} %")


if __name__ == "__main__":
    main()

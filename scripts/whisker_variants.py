#!/usr/bin/env python3
"""Tracks one whisker video and its mirror images, and checks each with whisker_check.py: one real
case becomes four, so a change is judged on several runs instead of one.

Why: on the shared real video the tracker's figures move by a point or two from changes that
should not matter (a different rounding of a filter, a neighbouring setting), because a faint
whisker is kept or lost and the association follows. A mirrored or rotated copy of the same
frames (decoded once, written losslessly) has the same whiskers and the same difficulty but
rounds differently everywhere, so the mean over the copies separates what a change does from
what one run happened to do. Measured on ../shared/data/whiskers/test_video_10s.mp4 (default
settings, 2026-12-05): on a ridge 95.2 / 94.3 / 95.4 / 95.5 % of all whisker-frames (original,
mirrored left to right, top to bottom, rotated by 180°); with 8 search lines of ±2 px per element
instead of 4 of ±4 px, 95.2 / 95.3 / 94.7 / 95.1; with the follicle's search at 10 grey levels per pixel
instead of 6, 91.8 / 90.9 / 91.5 / 91.6 (and 90.9 / 92.5 / 92.4 / 91.6 before the beam element's
tangent was written out, which rounds differently); with the 80 % detection cover of before 90.5 / 91.4 /
91.3 / 89.9 %; four samples per element instead of eight (with 80 %): 88.5 / 87.4 / 89.9 /
88.1 %.

    scripts/whisker_variants.py --video ../shared/data/whiskers/test_video_10s.mp4 --face left \
        [--tracker build/release/tools/sinew-track] [--work DIR] [-- extra sinew-track options]

Prints one line per variant (whisker-frames on a ridge, of the tracked and of all, by both of
whisker_check.py's measures; lost, on a pole; identity: follicle jumps and the largest median
drift of a follicle from its first position; the tracker's median latency) and the mean and the
worst over the variants. Exits 1 when a run fails or a whisker-frame lies on a pole.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

import cv2

# name: (flip code for cv2.flip or None, how the face's side maps)
VARIANTS = {
    "original": (None, {}),
    "mirror-x": (1, {"left": "right", "right": "left"}),
    "mirror-y": (0, {"top": "bottom", "bottom": "top"}),
    "rotate-180": (-1, {"left": "right", "right": "left", "top": "bottom", "bottom": "top"}),
}


def write_frames(video, variants, work):
    """Decodes every frame of video once and writes it, flipped as each variant asks, as one
    lossless PNG sequence per variant (work/NAME/frames). Returns the pattern per variant and the
    frame count."""
    dirs = {name: os.path.join(work, name, "frames") for name in variants}
    for d in dirs.values():
        os.makedirs(d, exist_ok=True)
    cap = cv2.VideoCapture(video)
    if not cap.isOpened():
        sys.exit(f"{video}: cannot open")
    count = 0
    while True:
        ok, frame = cap.read()
        if not ok:
            break
        for name, d in dirs.items():
            flip = VARIANTS[name][0]
            out = frame if flip is None else cv2.flip(frame, flip)
            cv2.imwrite(os.path.join(d, f"f_{count:05d}.png"), out)
        count += 1
    if count == 0:
        sys.exit(f"{video}: no frames")
    return {name: os.path.join(d, "f_%05d.png") for name, d in dirs.items()}, count


def figure(pattern, text, what):
    m = re.search(pattern, text)
    if not m:
        sys.exit(f"no {what} in:\n{text}")
    return m


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--video", required=True)
    ap.add_argument("--face", required=True, choices=["left", "right", "top", "bottom"],
                    help="the face's side in the original video")
    ap.add_argument("--tracker", default=os.path.join(here, "..", "build", "release", "tools",
                                                      "sinew-track"))
    ap.add_argument("--work", help="keep frames and results here (default: a temporary folder, "
                    "removed at the end)")
    ap.add_argument("--variants", default=",".join(VARIANTS),
                    help="comma-separated subset of " + ", ".join(VARIANTS))
    ap.add_argument("extra", nargs="*", help="options passed to sinew-track (after --)")
    args = ap.parse_args()
    names = [v for v in args.variants.split(",") if v]
    for name in names:
        if name not in VARIANTS:
            sys.exit(f"--variants: unknown variant '{name}' (known: {', '.join(VARIANTS)})")
    scratch = None if args.work else tempfile.TemporaryDirectory(prefix="sinew_variants_")
    work = args.work or scratch.name
    check = os.path.join(here, "whisker_check.py")
    rows = []
    failed = False
    patterns, frames = write_frames(args.video, names, work)
    for name in names:
        face = VARIANTS[name][1].get(args.face, args.face)
        pattern = patterns[name]
        results = os.path.join(work, name, "results.jsonl")
        track = subprocess.run([args.tracker, "--input", pattern, "--whiskers", "--face", face,
                                "--out", results] + args.extra,
                               capture_output=True, text=True)
        if track.returncode != 0:
            print(f"{name}: sinew-track failed ({track.returncode}):\n{track.stderr}")
            failed = True
            continue
        latency = re.search(r"latency per frame \(all whiskers\): median ([0-9.]+) us",
                            track.stdout + track.stderr)
        checked = subprocess.run([sys.executable, check, "--video", pattern, "--results",
                                  results], capture_output=True, text=True)
        if checked.returncode != 0:
            print(f"{name}: whisker_check.py failed:\n{checked.stdout}{checked.stderr}")
            failed = True
            continue
        out = checked.stdout
        total = figure(r"whisker-frames: (\d+), tracked \(ok or not_converged\) (\d+)", out,
                       "whisker-frame count")
        ridge = figure(r"on a dark ridge .*: (\d+) = ([0-9.]+)% of tracked, ([0-9.]+)% of all",
                       out, "on-ridge figure")
        near = figure(r"each side the brightest sample .*: (\d+) = ([0-9.]+)% of tracked, "
                      r"([0-9.]+)% of all", out, "brightest-sides figure")
        pole = int(figure(r"on a pole or other thick dark object: (\d+)", out, "pole figure")[1])
        # Identity: follicle jumps between tracked frames and each whisker's median distance from
        # its first follicle (a whisker taken over by a neighbour drifts by the neighbours' spacing).
        identity = re.findall(r"(\d+): (\d+), ([0-9.]+) px",
                              figure(r"follicle jumps .*", out, "identity figures")[0])
        jumps = sum(int(j) for _, j, _ in identity)
        drift_id, _, drift = max(identity, key=lambda t: float(t[2]), default=("-", 0, "nan"))
        row = {
            "name": name, "face": face, "frames": frames,
            "tracked": float(ridge[2]), "all": float(ridge[3]),
            "near_tracked": float(near[2]), "near_all": float(near[3]),
            "lost": int(total[1]) - int(total[2]), "pole": pole,
            "latency_us": float(latency[1]) if latency else float("nan"),
            "jumps": jumps, "drift_px": float(drift), "drift_id": drift_id,
        }
        failed = failed or pole > 0
        rows.append(row)
        print(f"{name:11s} face {face:6s} {frames} frames: on a ridge {row['tracked']:5.1f} % of "
              f"tracked, {row['all']:5.1f} % of all (brightest sides {row['near_tracked']:.1f} / "
              f"{row['near_all']:.1f} %); lost {row['lost']}; on a pole {pole}; "
              f"follicle jumps {jumps}, largest drift {row['drift_px']:.1f} px (id {drift_id}); "
              f"median latency {row['latency_us']:.0f} us", flush=True)
    if rows:
        mean_all = sum(r["all"] for r in rows) / len(rows)
        mean_tracked = sum(r["tracked"] for r in rows) / len(rows)
        worst = min(rows, key=lambda r: r["all"])
        mean_jumps = sum(r["jumps"] for r in rows) / len(rows)
        mean_near = sum(r["near_all"] for r in rows) / len(rows)
        worst_near = min(r["near_all"] for r in rows)
        print(f"mean over {len(rows)} variants: on a ridge {mean_tracked:.1f} % of tracked, "
              f"{mean_all:.1f} % of all; worst {worst['all']:.1f} % of all ({worst['name']}); "
              f"brightest sides {mean_near:.1f} % of all, worst {worst_near:.1f} %; "
              f"follicle jumps {mean_jumps:.0f}, largest drift "
              f"{max(r['drift_px'] for r in rows):.1f} px")
    if scratch:
        scratch.cleanup()
    sys.exit(1 if failed or not rows else 0)


if __name__ == "__main__":
    main()

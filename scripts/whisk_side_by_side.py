#!/usr/bin/python3
"""Janelia whisk's `trace` and sinew-track --whiskers timed on the same frames in one run (issue 50).

    whisk_side_by_side.py --trace WHISK_BUILD/trace --build-dir build/release \\
                          FRAMES_DIR[:FACE] [FRAMES_DIR[:FACE] ...] [--repeat 2]

Each FRAMES_DIR holds one video's frames as PNG files (e.g. the whisker benchmark's cached variants,
build/whisker_bench_cache/video/<variant>/frames); they are written once as a multi-page TIFF for
whisk (its reader without FFmpeg). whisk runs once unmeasured first (it builds its detector bank
beside the output on its first run), then both tools alternate `--repeat` times. The figure is CPU
time (user + system) per frame, so that a machine busy with other work still gives a per-core rate;
wall time is printed beside it. How to build whisk: docs/whisker_batch.md, "whisk side by side".
"""
import argparse
import glob
import os
import re
import resource
import subprocess
import sys
import tempfile
import time

import cv2


def timed(cmd, cwd):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.time()
    r = subprocess.run(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.time() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr[-500:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("videos", nargs="+", help="FRAMES_DIR[:FACE] (face default left)")
    ap.add_argument("--trace", required=True, help="whisk's trace executable")
    ap.add_argument("--build-dir", default="build/release")
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    track = os.path.join(os.path.abspath(args.build_dir), "tools", "sinew-track")
    trace = os.path.abspath(args.trace)
    work = tempfile.mkdtemp(prefix="whisk_side_by_side.")
    print(f"{'video':<28} {'frames':>6} {'size':>9} | {'whisk fps/core':>14} {'sinew fps/core':>14}"
          f" {'sinew / whisk':>13} | wall s whisk / sinew")
    for spec in args.videos:
        folder, _, face = spec.partition(":")
        folder = os.path.abspath(folder)
        files = sorted(glob.glob(os.path.join(folder, "*.png")))
        if not files:
            sys.exit(f"{folder}: no PNG frames")
        name = os.path.basename(os.path.dirname(folder.rstrip("/"))) or os.path.basename(folder)
        images = [cv2.imread(f, cv2.IMREAD_GRAYSCALE) for f in files]
        tif = os.path.join(work, name + ".tif")
        cv2.imwritemulti(tif, images)
        h, w = images[0].shape
        m = re.fullmatch(r"(.*?)(\d+)\.png", os.path.basename(files[0]))
        if not m:
            sys.exit(f"{files[0]}: frames are named PREFIX<digits>.png")
        pattern = os.path.join(folder, f"{m.group(1)}%0{len(m.group(2))}d.png")
        timed([trace, tif, os.path.join(work, name)], work)  # builds the detector bank
        whisk, sinew = [], []
        for _ in range(args.repeat):
            whisk.append(timed([trace, tif, os.path.join(work, name)], work))
            sinew.append(timed([track, "--input", pattern, "--whiskers", "--face", face or "left",
                                "--out", os.path.join(work, name + ".jsonl"), "--quiet"], work))
        n = len(files)
        wf = n / min(c for c, _ in whisk)
        sf = n / min(c for c, _ in sinew)
        print(f"{name:<28} {n:>6} {w:>4}x{h:<4} | {wf:>14.1f} {sf:>14.1f} {sf / wf:>12.2f}x |"
              f" {' '.join(f'{x:.1f}' for _, x in whisk)} / {' '.join(f'{x:.1f}' for _, x in sinew)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

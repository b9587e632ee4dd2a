#!/usr/bin/env python3
"""A whisker video tracked in chunks against the same video tracked in one pass (issue 50).

    whisker_chunk_check.py ONE_PASS/results.jsonl CHUNKED/results.jsonl [--tolerance-px 0.5]
                           [--max-border-frames N] [--min-agreement F]

A whisker-frame agrees when the chunked results have the one pass's id on that frame, both tracked
(not lost), their curves within the tolerance (mean distance of each curve's nodes to the other
polyline, over the part the two share); it is missing when the chunked results do not have the id on that frame (the chunk's own
detection did not find that whisker), counted apart, as are whiskers only the chunks have (a
chunk's detection found a whisker the one pass's did not). For each border (the chunks' `output_from`, from the detection line's "chunks" record) it
prints the frames after the border up to the last that disagrees before the next border (N), and
the agreement over all frames and over the frames more than N_max after a border. Exit status 1
when a border's N exceeds --max-border-frames or the agreement away from the borders is below
--min-agreement.
"""
import argparse
import json
import math
import sys


def read(path):
    detection, frames = None, {}
    with open(path) as f:
        for line in f:
            j = json.loads(line)
            if "detection" in j:
                detection = j["detection"]
            else:
                frames[j["frame"]] = {w["id"]: w for w in j["whiskers"]}
    return detection, frames


def one_sided(a, b):
    """Mean distance of a's nodes to polyline b, over nodes whose nearest point is not b's end."""
    total, n = 0.0, 0
    for px, py in a:
        best, interior = math.inf, False
        for i in range(len(b) - 1):
            (x0, y0), (x1, y1) = b[i], b[i + 1]
            ex, ey = x1 - x0, y1 - y0
            len2 = ex * ex + ey * ey
            t = ((px - x0) * ex + (py - y0) * ey) / len2 if len2 > 0 else 0.0
            end = (i == 0 and t < 0) or (i == len(b) - 2 and t > 1)
            t = min(max(t, 0.0), 1.0)
            d = math.hypot(x0 + t * ex - px, y0 + t * ey - py)
            if d < best:
                best, interior = d, not end
        if interior:
            total, n = total + best, n + 1
    return total / n if n else math.nan


def distance(wa, wb):
    a = [(n[0], n[1]) for n in wa["nodes"]]
    b = [(n[0], n[1]) for n in wb["nodes"]]
    d = [x for x in (one_sided(a, b), one_sided(b, a)) if not math.isnan(x)]
    return sum(d) / len(d) if d else math.inf


def tracked(w):
    return w is not None and w["status"] != "lost" and len(w["nodes"]) > 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("one_pass")
    ap.add_argument("chunked")
    ap.add_argument("--tolerance-px", type=float, default=0.5)
    ap.add_argument("--max-border-frames", type=int, default=None)
    ap.add_argument("--min-agreement", type=float, default=None)
    ap.add_argument("--max-missing", type=float, default=None,
                    help="largest fraction of the one pass's whisker-frames missing from the chunks")
    args = ap.parse_args()
    _, one = read(args.one_pass)
    detection, chunked = read(args.chunked)
    if not detection or "chunks" not in detection:
        sys.exit(f"{args.chunked}: no \"chunks\" record in its detection line (not stitched)")
    borders = [c["output_from"] for c in detection["chunks"][1:]]
    bad_frames = set()
    whisker_frames = agree = missing = extra = 0
    missing_ids = {}
    for f, ws in one.items():
        other = chunked.get(f, {})
        ok = True
        extra += sum(1 for i, o in other.items() if i not in ws and tracked(o))
        for i, w in ws.items():
            if not tracked(w):
                continue
            whisker_frames += 1
            o = other.get(i)
            if o is None:  # a whisker the chunk's detection did not find
                missing += 1
                missing_ids[i] = missing_ids.get(i, 0) + 1
                continue
            good = tracked(o) and distance(w, o) <= args.tolerance_px
            agree += good
            ok = ok and good
        if not ok:
            bad_frames.add(f)
    ends = borders[1:] + [max(one) + 1]
    worst = 0
    for b, e in zip(borders, ends):
        late = [f - b + 1 for f in bad_frames if b <= f < e]
        n = max(late, default=0)
        worst = max(worst, n)
        print(f"border at frame {b}: the whiskers both have agree from {n} frames after it "
              f"({len(late)} frames of {e - b} disagree)")
    near = set()
    limit = args.max_border_frames if args.max_border_frames is not None else worst
    for b in borders:
        near.update(range(b, b + limit))
    away = [f for f in one if f not in near]
    away_bad = sum(f in bad_frames for f in away)
    away_agreement = 1.0 - away_bad / max(len(away), 1)
    print(f"whisker-frames of the one pass: {whisker_frames}; agreeing within "
          f"{args.tolerance_px} px: {agree} ({agree / max(whisker_frames, 1):.4f}); missing from "
          f"the chunks (not found by a chunk's detection): {missing} "
          f"({missing / max(whisker_frames, 1):.4f}; by id {dict(sorted(missing_ids.items()))}); "
          f"whisker-frames only the chunks have (whiskers the one pass's detection missed): {extra}")
    print(f"frames whose common whiskers agree more than {limit} frames after a border: "
          f"{len(away) - away_bad} of {len(away)} ({away_agreement:.4f}); N = {worst}")
    failed = False
    if args.max_border_frames is not None and worst > args.max_border_frames:
        print(f"FAIL: a border's N is {worst} > {args.max_border_frames}")
        failed = True
    if args.min_agreement is not None and away_agreement < args.min_agreement:
        print(f"FAIL: agreement away from the borders {away_agreement:.4f} < {args.min_agreement}")
        failed = True
    if args.max_missing is not None and missing > args.max_missing * whisker_frames:
        print(f"FAIL: {missing} whisker-frames missing > {args.max_missing} of {whisker_frames}")
        failed = True
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())

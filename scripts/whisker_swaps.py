#!/usr/bin/env python3
"""Where the identity swaps of a sinew-track run on a ../shared whisker_pad render come from.

  scripts/whisker_swaps.py RENDER_DIR RESULTS.jsonl [--list]

Matches the run's curves to the truth exactly as ../shared/tools/whisker_pad/score.py does (its
functions, imported, not copied: per frame the Hungarian method on the mean distance of the
tracker's nodes to each true whisker, a match within GATE_PX; a swap is a tracker id matched to
another true whisker than the last time it was matched), and puts each swap in one class by what
sinew-track reported for that id between the two matches:

  a  the association restarted the id on a detection (`reacquired`) while its fit was kept: a
     redetection gave a tracked whisker another trace;
  b  no restart, and the fit moved by more than 1 px (mean over its nodes) or no longer lies
     within the gate of its old whisker: the tracker's own fit slid onto a neighbour;
  c  the id was lost or not converged in between (restarted or not) and came back on another
     whisker: lost and re-added under another id;
  d  no restart, the fit moved by at most 1 px and still lies within the gate of its old whisker:
     the scorer's matching of a curve that lies near two true whiskers (a partial curve, a
     converging pair).

For class a it also counts the swaps onto a true whisker no id held on the frame before (a
whisker without an identity of its own, e.g. one not found on frame 0), those on a frame with
another class-a swap (a shift of the whole row), and those back on the old whisker within 5 frames.
"""
import collections
import json
import os
import sys

import numpy as np
from scipy.optimize import linear_sum_assignment

HERE = os.path.dirname(os.path.abspath(__file__))
PAD_TOOL = os.path.join(HERE, "..", "..", "shared", "tools", "whisker_pad")


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if len(args) != 2:
        print(__doc__)
        return 2
    if not os.path.exists(os.path.join(PAD_TOOL, "score.py")):
        print(f"{PAD_TOOL}/score.py: absent")
        return 77
    sys.path.insert(0, PAD_TOOL)
    import score as S  # noqa: E402  (../shared's scorer, used unchanged)

    outdir, results = args
    truth = json.load(open(os.path.join(outdir, "truth.json")))
    rows = S.load_results(results)
    n_truth = len(truth["whiskers"])
    history = collections.defaultdict(dict)  # id -> frame -> whisker record (any status)
    for f, r in rows.items():
        for w in r.get("whiskers", []):
            history[w["id"]][f] = w
    last, swaps, held = {}, [], collections.defaultdict(set)
    for fr in truth["frames"]:
        f = fr["frame"]
        r = rows.get(f)
        if r is None:
            continue
        trk = [w for w in r["whiskers"]
               if w.get("status") in S.OK_STATUSES and len(w.get("nodes") or []) >= 1]
        if not trk:
            continue
        T = [np.asarray(tw["nodes"], float)[:, :2] for tw in fr["whiskers"]]
        Q = [np.asarray([p[:2] for p in w["nodes"]], float) for w in trk]
        C = np.array([[S.pt_poly_dist(q, t).mean() for q in Q] for t in T])
        for i, j in zip(*linear_sum_assignment(C)):
            if C[i, j] > S.GATE_PX:
                continue
            tid = trk[j]["id"]
            held[f].add(i)
            if tid in last and last[tid][0] != i:
                swaps.append((f, tid, last[tid][0], i, last[tid][1], C[:, j].copy()))
            last[tid] = (i, f)

    def nodes(w):
        return np.asarray([p[:2] for p in w["nodes"]], float)

    classes, listed = collections.Counter(), []
    for f, tid, old, new, before, cost in swaps:
        h = history[tid]
        restarted = any(h[g].get("reacquired") for g in range(before + 1, f + 1) if g in h)
        not_ok = any(h[g]["status"] != "ok" for g in range(before + 1, f) if g in h)
        moved = (np.linalg.norm(nodes(h[f]) - nodes(h[before]), axis=1).mean()
                 if len(h[f]["nodes"]) == len(h[before]["nodes"]) else float("inf"))
        if not_ok:
            c = "c"
        elif restarted:
            c = "a"
        elif moved <= 1.0 and cost[old] <= S.GATE_PX:
            c = "d"
        else:
            c = "b"
        classes[c] += 1
        listed.append((f, tid, old, new, c, moved))
    a = [s for s in listed if s[4] == "a"]
    per_frame = collections.Counter(s[0] for s in a)
    row_shift = sum(1 for s in a if per_frame[s[0]] >= 2)
    back = sum(1 for s in a if any(t[1] == s[1] and t[3] == s[2] and s[0] < t[0] <= s[0] + 5
                                   for t in listed))
    unheld = sum(1 for s in a if s[3] not in held.get(s[0] - 1, set()))
    print(f"{os.path.basename(os.path.normpath(outdir))}: swaps {len(swaps)}: "
          + ", ".join(f"{k} {classes[k]}" for k in "abcd")
          + f"; ids {len(history)} for {n_truth} true whiskers")
    print(f"  a: onto a whisker no id held the frame before {unheld}, with another a-swap on the "
          f"frame {row_shift}, back within 5 frames {back}")
    if "--list" in sys.argv:
        for f, tid, old, new, c, moved in listed:
            print(f"  frame {f} id {tid}: w{old} -> w{new} class {c} (fit moved {moved:.2f} px)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Reads sinew-track --whiskers' CSV table, HDF5 file and plots the way a whisker lab's Python
does (pandas, h5py), and checks them: the documented columns with their units, one row per whisker
per frame, read-out values on every ok row and none on the others, ids and frames as in the JSON
Lines, SI magnitudes of a hair; the HDF5 summary equal to the CSV and its centrelines equal to the
JSON Lines' nodes.
  whisker_table_check.py --csv T.csv --hdf5 T.h5 --jsonl R.jsonl --plots DIR
"""
import argparse
import json
import math
import os
import sys

import h5py
import numpy as np
import pandas as pd


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--csv", required=True)
    ap.add_argument("--jsonl", required=True)
    ap.add_argument("--plots", required=True)
    ap.add_argument("--hdf5", required=True)
    a = ap.parse_args()
    d = pd.read_csv(a.csv)
    want = ["frame", "id", "status", "follicle_x_px", "follicle_y_px", "tip_x_px", "tip_y_px",
            "length_px", "base_angle_deg", "curvature_per_mm", "delta_curvature_per_mm", "m0_N_m",
            "contact", "contact_arc_length_px", "contact_force_x_N", "contact_force_y_N",
            "contact_moment_N_m", "pammer_moment_N_m", "follicle_force_axial_N",
            "follicle_force_lateral_N", "contact_force_sd_N", "contact_moment_sd_N_m",
            "follicle_force_axial_sd_N", "follicle_force_lateral_sd_N", "m0_sd_N_m"]
    failures = []
    if list(d.columns) != want:
        failures.append(f"columns {list(d.columns)}, expected {want}")
    frames = {}
    with open(a.jsonl) as f:
        for line in f:
            rec = json.loads(line)
            if "frame" in rec:
                frames[rec["frame"]] = rec["whiskers"]
    rows = sum(len(w) for w in frames.values())
    if len(d) != rows:
        failures.append(f"{len(d)} rows, the JSON Lines have {rows} whisker-frames")
    ok = d[d.status == "ok"]
    others = d[d.status != "ok"]
    values = ["base_angle_deg", "curvature_per_mm", "delta_curvature_per_mm", "m0_N_m"]
    if ok[values].isna().any().any():
        failures.append("an ok row lacks a read-out value")
    # Detection runs on every frame (the default), so every ok row says whether it touches, and
    # a contact point only when it does.
    if not ok.contact.isin([0, 1]).all():
        failures.append("an ok row's contact is not 0 or 1")
    if ok[ok.contact == 1].contact_arc_length_px.isna().any() or \
            ok[ok.contact == 0].contact_arc_length_px.notna().any():
        failures.append("contact_arc_length_px is not set exactly on the touching rows")
    if not others[values].isna().all().all():
        failures.append("a lost or not-converged row has read-out values")
    # The contact load: on touching rows only (after the rest frame, the first here).
    if ok[ok.contact == 0].contact_moment_N_m.notna().any():
        failures.append("contact_moment_N_m set on a row without contact")
    # The follicle carries the contact's load (statics: its reaction is the contact force's
    # opposite), so its two components are the contact force's magnitude; and nothing when the
    # whisker touches nothing.
    follicle = ["follicle_force_axial_N", "follicle_force_lateral_N"]
    if (ok[ok.contact == 0][follicle].abs() > 0).any().any() or \
            ok[ok.contact == 0][follicle].isna().any().any():
        failures.append("a row without contact has a follicle force other than 0")
    loaded = ok[ok.contact_force_x_N.notna()]
    if len(loaded) and not np.allclose(np.hypot(loaded.follicle_force_axial_N,
                                                loaded.follicle_force_lateral_N),
                                       np.hypot(loaded.contact_force_x_N, loaded.contact_force_y_N),
                                       rtol=1e-6, atol=0):
        failures.append("the follicle force is not the contact force's size")
    if (ok.contact_force_x_N.isna() & ok.follicle_force_axial_N.notna() & (ok.contact == 1)).any():
        failures.append("a follicle force on a touching row without a found contact load")
    # Every found load carries its standard deviations, positive; a follicle force of zero (no
    # contact) carries zero; and the moment's SD is the force's times the same arm.
    sds = ["contact_force_sd_N", "contact_moment_sd_N_m", "follicle_force_axial_sd_N",
           "follicle_force_lateral_sd_N"]
    if len(loaded) and not (loaded[sds] > 0).all().all():
        failures.append("a found contact load without positive standard deviations")
    if ok[ok.contact_force_x_N.isna()][sds[:2]].notna().any().any():
        failures.append("a contact load SD on a row without a found load")
    if (ok[ok.contact == 0][sds[2:]].abs() > 0).any().any():
        failures.append("a row without contact has a follicle force SD other than 0")
    if len(loaded):
        force = np.hypot(loaded.contact_force_x_N, loaded.contact_force_y_N)
        arm = loaded.contact_moment_N_m.abs() / force
        if not np.allclose(loaded.contact_moment_sd_N_m[force > 0],
                           (arm * loaded.contact_force_sd_N)[force > 0], rtol=1e-6, atol=0):
            failures.append("the contact moment's SD is not the force's times its arm")
    # M0's noise level, measured on each whisker's frames touching nothing: set on ok rows once
    # enough were seen, never on the others; in the same unit as M0, so that M0 lies within
    # 3 of it on most frames without contact (where nothing but noise bends the whisker).
    if others.m0_sd_N_m.notna().any():
        failures.append("a lost or not-converged row has an M0 SD")
    with_sd = ok[ok.m0_sd_N_m.notna()]
    if len(with_sd) < len(ok) // 2 or not (with_sd.m0_sd_N_m > 0).all():
        failures.append(f"M0 SD set on {len(with_sd)} of {len(ok)} ok rows, or not positive")
    quiet = with_sd[with_sd.contact == 0]
    within = (quiet.m0_N_m.abs() <= 3 * quiet.m0_sd_N_m).mean() if len(quiet) else 0.0
    if within < 0.9:
        failures.append(f"|M0| within 3 SD on {within:.2f} of the rows without contact")
    # The JSON record of each ok whisker-frame carries the same numbers.
    for _, r in ok.head(50).iterrows():
        w = next(w for w in frames[int(r.frame)] if w["id"] == int(r.id))
        if not math.isclose(w["m0_N_m"], r.m0_N_m, rel_tol=1e-6, abs_tol=1e-18):
            failures.append(f"frame {r.frame} whisker {r.id}: m0 {r.m0_N_m} vs JSON {w['m0_N_m']}")
        # JSON null (no load found) is an empty CSV cell.
        jm = w.get("contact_moment_N_m")
        if (jm is not None) != (not math.isnan(r.contact_moment_N_m)) or (
                jm is not None and not math.isclose(jm, r.contact_moment_N_m, rel_tol=1e-6)):
            failures.append(f"frame {r.frame} whisker {r.id}: contact moment differs from JSON")
            break
    # The first frame is the rest: Δκ and M0 zero there; later a hair's moments are far below
    # 1e-4 N m (a 40 µm whisker bent to a 1 mm radius carries ~2e-6 N m).
    first = ok[ok.frame == ok.frame.min()]
    if (first[["delta_curvature_per_mm", "m0_N_m"]].abs() > 1e-12).any().any():
        failures.append("the first frame's delta_curvature or m0 is not 0")
    if (ok.m0_N_m.abs() > 1e-4).any():
        failures.append(f"moments up to {ok.m0_N_m.abs().max()} N m: not a hair's")
    for i in sorted(d.id.unique()):
        png = os.path.join(a.plots, f"whisker_{i}.png")
        if not os.path.isfile(png) or os.path.getsize(png) < 1000:
            failures.append(f"{png} missing")
    with h5py.File(a.hdf5, "r") as f:
        h = pd.DataFrame(f["summary"][:])
        h["status"] = h.status.str.decode("ascii")
        if list(h.columns) != want:
            failures.append(f"HDF5 summary columns {list(h.columns)}, expected {want}")
        elif not ((h.frame.to_numpy() == d.frame.to_numpy()).all() and
                  (h.id.to_numpy() == d.id.to_numpy()).all() and
                  (h.status.to_numpy() == d.status.to_numpy()).all() and
                  np.allclose(h[want[3:]].to_numpy(), d[want[3:]].to_numpy(), rtol=1e-7,
                              atol=1e-12, equal_nan=True)):
            failures.append("the HDF5 summary differs from the CSV table")
        order = sorted(frames)
        if list(f["frame"][:]) != order:
            failures.append("HDF5 /frame differs from the JSON Lines' frames")
        for i in sorted(d.id.unique()):
            c = f[f"centrelines/whisker_{i}"][:]
            for k, fr in enumerate(order):
                w = next(w for w in frames[fr] if w["id"] == i)
                if w["status"] == "lost":
                    if not np.isnan(c[k]).all():
                        failures.append(f"whisker {i} frame {fr}: lost but HDF5 nodes are set")
                        break
                elif not np.allclose(c[k], np.array(w["nodes"]), rtol=1e-9, atol=1e-9):
                    failures.append(f"whisker {i} frame {fr}: HDF5 nodes differ from the JSON")
                    break
    print(f"{len(d)} rows, {len(ok)} ok, {d.id.nunique()} whiskers; M0 median |{ok.m0_N_m.abs().median():.3g}| N m,"
          f" base angle {ok.base_angle_deg.min():.1f}..{ok.base_angle_deg.max():.1f} deg")
    for f in failures:
        print("FAIL:", f)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()

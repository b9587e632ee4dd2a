#!/usr/bin/env python3
"""A small free-object case like the vertebrae of ../shared/data/vertebrae, from the demo case.

`sinew-register --make-demo-case DEMO` writes a capsule stretched and bent by a known deformation;
this drops its attachments, takes eight landmarks from template vertices and their known images,
keeps its 80 ICP markers and the tool's defaults otherwise (damped steps, predictor warm start,
landmarks in the ICP stage), with a coarse mesh and 26 iterations so that a run takes seconds:
with landmarks the tool's ICP weight ramp takes 21 (from 1e-7 of alpha), so the last 5 are at the
full weight, where steps clamp tets and the damping works, as on the vertebrae.
Writes DEMO/free_case.json. Used by register_stability_sweep.sh and register_rotated_test.sh.

    make_free_demo_case.py DEMO [EXTRA_SOLVER_JSON]

EXTRA_SOLVER_JSON (optional) is merged into the case's "solver" object.
"""
import json
import sys

demo = sys.argv[1]
extra = json.loads(sys.argv[2]) if len(sys.argv) > 2 else {}


def obj_vertices(path):
    return [tuple(map(float, l.split()[1:4])) for l in open(path) if l.startswith("v ")]


template = obj_vertices(demo + "/template.obj")
truth = obj_vertices(demo + "/truth_surface.obj")
assert len(template) == len(truth), "template and truth differ in vertex count"
# Eight landmarks spread over the vertex list (the capsule's rings run along x).
picks = [round(i * (len(template) - 1) / 7) for i in range(8)]
case = json.load(open(demo + "/case.json"))
del case["attachments"]
case["landmarks"] = [{"template": list(template[i]), "target": list(truth[i]),
                      "label": "L%d" % n} for n, i in enumerate(picks)]
# The markers inline (scripts/register_rotated.py rotates inline points only).
if isinstance(case.get("icp_markers"), str):
    with open(demo + "/" + case["icp_markers"]) as f:
        rows = [l.strip().split(",") for l in f if l.strip()]
    case["icp_markers"] = [[float(v) for v in r[:3]] for r in rows if r[0] != "x"]
case["mesh"] = {"cell_size_fraction": 0.12, "facet_distance_fraction": 0.008}
case["stop"] = {"max_iterations": 26}
case.setdefault("solver", {}).update(extra)
json.dump(case, open(demo + "/free_case.json", "w"), indent=1)

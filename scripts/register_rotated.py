#!/usr/bin/env python3
"""Frame independence of sinew-register (issue 18): the person's scan in another orientation.

For a registration case (case.json with landmarks and/or ICP markers, free object) and the
person's full surface, writes a copy whose target side (landmark targets, ICP markers, truth
surface) is rotated by ANGLE degrees about an oblique axis through the origin (default
(1, 2, 3)/|(1, 2, 3)|; the template is not touched: a user's template stays where it is, the scan
comes in the scanner's frame), runs sinew-register on the original and on each rotated copy,
rotates each rotated result back and prints the largest vertex distance between it and the
original result, in mm and as a fraction of the template surface's bounding-box diagonal, and
the two runs' report figures.

The template path is made absolute in the copies; other relative paths of the case (transfer,
scan_image) are not rewritten, and landmarks and markers must be inline.

Usage: register_rotated.py SINEW_REGISTER CASE_JSON TRUTH WORKDIR [--angles 90 180]
       [--tolerance 1e-4] [--axis 1 2 3]
Exit status 1 when a rotated result is farther than tolerance × diagonal from the original.
"""

import argparse
import json
import math
import os
import struct
import subprocess
import sys
import time


def rotation(axis, degrees):
    """Rodrigues: the 3x3 rotation (rows) by degrees about axis."""
    n = math.sqrt(sum(c * c for c in axis))
    x, y, z = (c / n for c in axis)
    t = math.radians(degrees)
    c, s, v = math.cos(t), math.sin(t), 1 - math.cos(t)
    return [[c + x * x * v, x * y * v - z * s, x * z * v + y * s],
            [y * x * v + z * s, c + y * y * v, y * z * v - x * s],
            [z * x * v - y * s, z * y * v + x * s, c + z * z * v]]


def apply(r, p):
    return [sum(r[i][j] * p[j] for j in range(3)) for i in range(3)]


def apply_transposed(r, p):
    return [sum(r[j][i] * p[j] for j in range(3)) for i in range(3)]


def read_obj(path):
    vertices, faces = [], []
    with open(path) as f:
        for line in f:
            p = line.split()
            if not p:
                continue
            if p[0] == "v":
                vertices.append([float(c) for c in p[1:4]])
            elif p[0] == "f":
                faces.append([int(c.split("/")[0]) - 1 for c in p[1:4]])
    return vertices, faces


def read_ply(path):
    """Vertices (x, y, z) and triangles of an ASCII or binary little-endian PLY."""
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline().decode("ascii").strip()
            header.append(line)
            if line == "end_header":
                break
        body = f.read()
    fmt = next(l.split()[1] for l in header if l.startswith("format"))
    elements, current = [], None
    for l in header:
        p = l.split()
        if p[0] == "element":
            current = [p[1], int(p[2]), []]
            elements.append(current)
        elif p[0] == "property":
            current[2].append(p[1:])
    sizes = {"float": "f", "float32": "f", "double": "d", "float64": "d", "uchar": "B",
             "uint8": "B", "char": "b", "int8": "b", "int": "i", "int32": "i", "uint": "I",
             "uint32": "I", "short": "h", "ushort": "H"}
    vertices, faces = None, []
    if fmt == "ascii":
        tokens = body.decode("ascii").split()
        pos = 0
        for name, count, props in elements:
            for _ in range(count):
                row = []
                for prop in props:
                    if prop[0] == "list":
                        n = int(tokens[pos]); pos += 1
                        row.append([int(t) for t in tokens[pos:pos + n]]); pos += n
                    else:
                        row.append(float(tokens[pos])); pos += 1
                if name == "vertex":
                    vertices = [] if vertices is None else vertices
                    vertices.append(row[:3])
                elif name == "face":
                    faces.append(row[0])
    else:
        assert fmt == "binary_little_endian", fmt
        pos = 0
        for name, count, props in elements:
            if all(p[0] != "list" for p in props):
                row = "<" + "".join(sizes[p[0]] for p in props)
                size = struct.calcsize(row)
                names = [p[1] for p in props]
                if name == "vertex":
                    xyz = [names.index(c) for c in "xyz"]
                    vertices = []
                    for i in range(count):
                        values = struct.unpack_from(row, body, pos + i * size)
                        vertices.append([float(values[j]) for j in xyz])
                pos += size * count
                continue
            for _ in range(count):
                row = []
                for prop in props:
                    if prop[0] == "list":
                        c = sizes[prop[1]]
                        (n,) = struct.unpack_from("<" + c, body, pos); pos += struct.calcsize(c)
                        t = sizes[prop[2]]
                        row.append(list(struct.unpack_from("<%d%s" % (n, t), body, pos)))
                        pos += n * struct.calcsize(t)
                    else:
                        t = sizes[prop[0]]
                        row.append(struct.unpack_from("<" + t, body, pos)[0]); pos += struct.calcsize(t)
                if name == "face":
                    faces.append(row[0])
    return vertices, [f[:3] for f in faces]


def read_surface(path):
    if path.lower().endswith(".ply"):
        return read_ply(path)
    if path.lower().endswith(".obj"):
        return read_obj(path)
    sys.exit("register_rotated.py: %s: only .obj and .ply surfaces are read here" % path)


def write_obj(path, vertices, faces):
    with open(path, "w") as f:
        for v in vertices:
            f.write("v %.17g %.17g %.17g\n" % tuple(v))
        for t in faces:
            f.write("f %d %d %d\n" % tuple(i + 1 for i in t))


def run(tool, case, truth, out):
    start = time.time()
    subprocess.run([tool, "--case", case, "--out", out, "--truth", truth, "--quiet"], check=True)
    seconds = time.time() - start
    with open(os.path.join(out, "report.json")) as f:
        report = json.load(f)
    vertices, _ = read_obj(os.path.join(out, "result_surface.obj"))
    return vertices, report, seconds


def summary(report, seconds):
    fin = report["final"]
    nan = float("nan")
    return ("%.3f mm; markers %.3f / %.3f; landmarks %.3f / %.3f; %s; %.0f s" % (
        report.get("truth", {}).get("symmetric_mean_area_sampled", nan),
        fin.get("marker_error_mean", nan), fin.get("marker_error_max", nan),
        fin.get("landmark_error_mean", nan), fin.get("landmark_error_max", nan),
        report["termination"], seconds))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("tool")
    parser.add_argument("case")
    parser.add_argument("truth")
    parser.add_argument("workdir")
    parser.add_argument("--angles", type=float, nargs="+", default=[90.0, 180.0])
    parser.add_argument("--axis", type=float, nargs=3, default=[1.0, 2.0, 3.0])
    parser.add_argument("--tolerance", type=float, default=1e-4)
    args = parser.parse_args()

    case_dir = os.path.dirname(os.path.abspath(args.case))
    with open(args.case) as f:
        case = json.load(f)
    template = case["template"]
    if not os.path.isabs(template):
        case["template"] = os.path.normpath(os.path.join(case_dir, template))
    for key in ("icp_markers", "landmarks"):
        if isinstance(case.get(key), (str, dict)):
            sys.exit("register_rotated.py: %s from a file: not supported (inline the points)" % key)
    if case.get("attachments"):
        sys.exit("register_rotated.py: an attached case is not frame independent (its "
                 "attachments hold the template in place)")
    os.makedirs(args.workdir, exist_ok=True)
    truth = os.path.abspath(args.truth)
    original_case = os.path.join(args.workdir, "case.json")
    with open(original_case, "w") as f:
        json.dump(case, f, indent=1)
    base, report, seconds = run(args.tool, original_case, truth, os.path.join(args.workdir, "out"))
    template_vertices, _ = read_surface(case["template"])
    diagonal = math.dist([min(v[i] for v in template_vertices) for i in range(3)],
                         [max(v[i] for v in template_vertices) for i in range(3)])
    print("unrotated: %s" % summary(report, seconds))
    truth_v, truth_f = read_surface(truth)
    worst = 0.0
    for angle in args.angles:
        r = rotation(args.axis, angle)
        rotated = json.loads(json.dumps(case))
        for lm in rotated.get("landmarks", []):
            lm["target"] = apply(r, lm["target"])
        if "icp_markers" in rotated:
            rotated["icp_markers"] = [apply(r, m) for m in rotated["icp_markers"]]
        folder = os.path.join(args.workdir, "rot%g" % angle)
        os.makedirs(folder, exist_ok=True)
        rotated_case = os.path.join(folder, "case.json")
        with open(rotated_case, "w") as f:
            json.dump(rotated, f, indent=1)
        rotated_truth = os.path.join(folder, "truth.obj")
        write_obj(rotated_truth, [apply(r, v) for v in truth_v], truth_f)
        result, report, seconds = run(args.tool, rotated_case, rotated_truth,
                                      os.path.join(folder, "out"))
        back = [apply_transposed(r, v) for v in result]
        gaps = [math.dist(a, b) for a, b in zip(back, base)]
        if len(back) != len(base):
            sys.exit("register_rotated.py: the results differ in vertex count")
        distance, mean = max(gaps), sum(gaps) / len(gaps)
        worst = max(worst, distance / diagonal)
        print("rotated %g deg: %s; from the unrotated result: max %.3g mm (%.2e of the %.1f mm "
              "diagonal), mean %.3g mm" % (angle, summary(report, seconds), distance,
                                          distance / diagonal, diagonal, mean))
    print("worst: %.2e of the diagonal (tolerance %.0e)" % (worst, args.tolerance))
    return 0 if worst <= args.tolerance else 1


if __name__ == "__main__":
    sys.exit(main())

"""sinew.register against sinew-register on the demo case (a capsule stretched and bent, ICP
markers on its known deformation): the same surface to 1e-9 and the same files, a dict case, and
errors as ValueError with the tool's one-line message.

Run by ctest (python_module) with PYTHONPATH=<build>/python and SINEW_BINARY_DIR=<build>; skipped
when the module was built without the offline library.
"""
import json
import os
import subprocess

import numpy as np
import pytest

import sinew

BIN = os.path.join(os.environ.get("SINEW_BINARY_DIR", "build/release"), "tools")
ITERATIONS = 2

pytestmark = pytest.mark.skipif(not hasattr(sinew, "register"),
                                reason="built without offline/ (no sinew.register)")


def read_obj_vertices(path):
    return np.array([[float(v) for v in line.split()[1:4]]
                     for line in open(path) if line.startswith("v ")])


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("register")
    subprocess.run([os.path.join(BIN, "sinew-register"), "--make-demo-case", str(out / "demo")],
                   check=True, capture_output=True)
    subprocess.run([os.path.join(BIN, "sinew-register"), "--case", str(out / "demo/case.json"),
                    "--out", str(out / "cli"), "--max-iterations", str(ITERATIONS), "--quiet"],
                   check=True, capture_output=True)
    return out


def test_same_surface_and_files_as_sinew_register(demo):
    r = sinew.register(str(demo / "demo/case.json"), out_dir=str(demo / "py"),
                       max_iterations=ITERATIONS)
    assert r["usable"]
    cli = read_obj_vertices(demo / "cli/result_surface.obj")
    assert r["vertices"].shape == cli.shape and r["faces"].shape[1] == 3
    np.testing.assert_allclose(r["vertices"], cli, rtol=0, atol=1e-9)
    assert r["Fp"].shape == (r["tets"].shape[0], 9)
    for name in ("result_surface.obj", "result.vtu"):
        assert (demo / "py" / name).read_bytes() == (demo / "cli" / name).read_bytes(), name
    report = json.load(open(demo / "cli/report.json"))
    assert r["report"]["final"] == report["final"]
    # The final marker errors (case units) are the report's.
    assert np.mean(r["marker_errors"]) == pytest.approx(report["final"]["marker_error_mean"],
                                                        rel=1e-12)
    assert np.max(r["marker_errors"]) == report["final"]["marker_error_max"]


def test_a_dict_case_resolves_files_against_the_working_folder(demo, monkeypatch):
    case = json.load(open(demo / "demo/case.json"))
    monkeypatch.chdir(demo / "demo")
    r = sinew.register(case, max_iterations=ITERATIONS)
    assert r["written"] == []
    cli = read_obj_vertices(demo / "cli/result_surface.obj")
    np.testing.assert_allclose(r["vertices"], cli, rtol=0, atol=1e-9)


def test_bad_input_raises_the_tools_message(demo, monkeypatch):
    case = json.load(open(demo / "demo/case.json"))
    monkeypatch.chdir(demo / "demo")
    case["stop"] = {"max_iterations": -1}
    with pytest.raises(ValueError, match="stop.max_iterations"):
        sinew.register(case)
    case = json.load(open(demo / "demo/case.json"))
    case["template"] = "missing.obj"
    with pytest.raises(ValueError, match="missing.obj"):
        sinew.register(case)

"""sinew.Whiskers against sinew-track --whiskers on a rendered whisker pad (sinew-synth): the same
whiskers, statuses, nodes, read-out and contacts, frame by frame, to 1e-9.

Run by ctest (python_module) with PYTHONPATH=<build>/python and SINEW_BINARY_DIR=<build>.
"""
import json
import os
import subprocess

import cv2
import numpy as np
import pytest

import sinew

BIN = os.path.join(os.environ.get("SINEW_BINARY_DIR", "build/release"), "tools")
FRAMES = 24


@pytest.fixture(scope="module")
def pad(tmp_path_factory):
    out = tmp_path_factory.mktemp("pad")
    subprocess.run([os.path.join(BIN, "sinew-synth"), "--scenario", "whisker-pad", "--frames",
                    str(FRAMES), "--out", str(out)], check=True, capture_output=True)
    results = out / "results.jsonl"
    subprocess.run([os.path.join(BIN, "sinew-track"), "--input", str(out / "frames/f_%04d.png"),
                    "--whiskers", "--face", "left", "--out", str(results), "--quiet"],
                   check=True, capture_output=True)
    lines = [json.loads(line) for line in open(results)]
    frames = [cv2.imread(str(out / f"frames/f_{k:04d}.png"), cv2.IMREAD_GRAYSCALE)
              for k in range(FRAMES)]
    return lines[0]["detection"], [line for line in lines if "whiskers" in line], frames, out


def test_same_whiskers_as_sinew_track(pad):
    detection, expected, frames, _ = pad
    whiskers = sinew.Whiskers(face="left")
    assert whiskers.detection is None
    compared = 0
    for frame, want in zip(frames, expected):
        got = whiskers.track(frame)
        assert len(got["whiskers"]) == len(want["whiskers"])
        for g, w in zip(got["whiskers"], want["whiskers"]):
            assert g["id"] == w["id"] and g["status"] == w["status"]
            np.testing.assert_allclose(g["nodes"], np.asarray(w["nodes"]), rtol=0, atol=1e-9)
            for key in ("base_angle_deg", "curvature_per_px", "delta_curvature_per_px",
                        "m0_model", "contact", "contact_arc_length_px"):
                assert (key in g) == (key in w), key
                if key in w:
                    assert g[key] == pytest.approx(w[key], rel=1e-9, abs=1e-12), key
                    compared += 1
    assert compared > 0
    found = whiskers.detection
    assert len(found["whiskers"]) == len(detection["whiskers"]) >= 8
    for g, w in zip(found["whiskers"], detection["whiskers"]):
        np.testing.assert_allclose(g["follicle"], w["follicle"], rtol=0, atol=1e-9)
        assert g["points"].shape[1] == 2


def test_detect_whiskers_on_one_frame(pad):
    """sinew.detect_whiskers finds on the first frame what sinew-track found there, and with
    keep_rejected says why the other traces were not whiskers."""
    detection, _, frames, _ = pad
    found = sinew.detect_whiskers(frames[0], face="left", keep_rejected=True)
    assert found["face"] == "left"
    assert len(found["whiskers"]) == len(detection["whiskers"]) >= 8
    for g, w in zip(found["whiskers"], detection["whiskers"]):
        np.testing.assert_allclose(g["follicle"], w["follicle"], rtol=0, atol=1e-9)
        assert g["length_px"] == pytest.approx(w["length_px"], rel=1e-9)
    reasons = {"not smooth", "not at the face", "does not leave the face", "too dark",
               "too short", "runs along a longer whisker", "off the pad"}
    assert all(r["reason"] in reasons and r["points"].shape[1] == 2 for r in found["rejected"])
    assert not sinew.detect_whiskers(frames[0], face="left")["rejected"]
    with pytest.raises(ValueError, match="no dark region touches the right border"):
        sinew.detect_whiskers(frames[0], face="right")


def test_home_follicles_as_sinew_track(pad):
    """associate_home_px reaches the tracker the same way from Python and from the command line."""
    _, _, frames, out = pad
    results = out / "home.jsonl"
    subprocess.run([os.path.join(BIN, "sinew-track"), "--input", str(out / "frames/f_%04d.png"),
                    "--whiskers", "--face", "left", "--associate-home-px", "15", "--out",
                    str(results), "--quiet"], check=True, capture_output=True)
    expected = [json.loads(line) for line in open(results)]
    expected = [line for line in expected if "whiskers" in line]
    whiskers = sinew.Whiskers(face="left", associate_home_px=15)
    for frame, want in zip(frames, expected):
        got = whiskers.track(frame)
        assert [g["status"] for g in got["whiskers"]] == [w["status"] for w in want["whiskers"]]
        for g, w in zip(got["whiskers"], want["whiskers"]):
            np.testing.assert_allclose(g["nodes"], np.asarray(w["nodes"]), rtol=0, atol=1e-9)


def test_force_recipe_as_sinew_track(pad):
    """The tracker's opt-in options for forces (docs/tracker.md: the line's position from the
    profile) reach it the same way from Python and from the command line, and change the result."""
    _, expected_default, frames, out = pad
    results = out / "recipe.jsonl"
    subprocess.run([os.path.join(BIN, "sinew-track"), "--input", str(out / "frames/f_%04d.png"),
                    "--whiskers", "--face", "left", "--profile-position", "--start-mean-surround-px",
                    "6", "--start-clearance-px", "2", "--fit-follicle-position", "--out",
                    str(results), "--quiet"], check=True, capture_output=True)
    expected = [json.loads(line) for line in open(results)]
    expected = [line for line in expected if "whiskers" in line]
    whiskers = sinew.Whiskers(face="left", profile_position=True, start_mean_surround_px=6,
                              start_clearance_px=2, fit_follicle_position=True)
    differs = 0
    for frame, want, default in zip(frames, expected, expected_default):
        got = whiskers.track(frame)
        assert [g["status"] for g in got["whiskers"]] == [w["status"] for w in want["whiskers"]]
        for g, w, d in zip(got["whiskers"], want["whiskers"], default["whiskers"]):
            np.testing.assert_allclose(g["nodes"], np.asarray(w["nodes"]), rtol=0, atol=1e-9)
            for key in ("contact_moment_model", "contact_force_model"):
                if key in w and w[key] is not None:
                    assert g[key] == pytest.approx(w[key], rel=1e-9, abs=1e-12), key
            differs += len(g["nodes"]) != len(d["nodes"]) or not np.allclose(
                g["nodes"], np.asarray(d["nodes"]), rtol=0, atol=1e-6)
    assert differs > 0


def test_bad_options_raise():
    with pytest.raises(ValueError, match="associate_home_px"):
        sinew.Whiskers(associate_home_px=-1)
    with pytest.raises(ValueError, match="face"):
        sinew.Whiskers(face="sideways")
    with pytest.raises(ValueError, match="base_radius_um"):
        sinew.Whiskers(mm_per_px=0.05)


def test_whisker_preset_is_its_values(pad):
    _, _, frames, _ = pad
    preset = sinew.Whiskers(face="left", mm_per_px=0.05, whisker_preset="rat-c2")
    given = sinew.Whiskers(face="left", mm_per_px=0.05, young_modulus_gpa=3.34,
                           base_radius_um=69.5, tip_radius_um=1.6, length_mm=33.6)
    compared = 0
    for frame in frames[:6]:
        a, b = preset.track(frame), given.track(frame)
        for wa, wb in zip(a["whiskers"], b["whiskers"]):
            assert wa.keys() == wb.keys()
            for key, value in wa.items():
                if isinstance(value, float):
                    assert value == wb[key], key
                    compared += key.endswith("_Nm") or key.startswith("m0")
    assert compared > 0
    with pytest.raises(ValueError, match="whisker_preset"):
        sinew.Whiskers(whisker_preset="mouse-x")

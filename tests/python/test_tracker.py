"""The Python module against sinew-track on the same frames: the same nodes and forces to 1e-9.

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


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    """A rendered cantilever under a growing tip load (sinew-synth), tracked by sinew-track."""
    out = tmp_path_factory.mktemp("cantilever")
    subprocess.run([os.path.join(BIN, "sinew-synth"), "--scenario", "cantilever", "--frames",
                    "12", "--noise", "8", "--clutter", "4", "--out", str(out)],
                   check=True, capture_output=True)
    results = out / "results.jsonl"
    subprocess.run([os.path.join(BIN, "sinew-track"), "--input", str(out / "frames/f_%04d.png"),
                    "--init", str(out / "init.json"), "--out", str(results)],
                   check=True, capture_output=True)
    lines = [json.loads(line) for line in open(results)]
    frames = [cv2.imread(str(out / f"frames/f_{k:04d}.png"), cv2.IMREAD_GRAYSCALE)
              for k in range(12)]
    return out, [line for line in lines if "nodes" in line], frames


def test_same_nodes_and_forces_as_sinew_track(sequence):
    out, expected, frames = sequence
    tracker = sinew.Tracker(str(out / "init.json"))
    assert len(expected) == len(frames)
    for frame, want in zip(frames, expected):
        got = tracker.track(frame)
        assert got["status"] == want["status"]
        np.testing.assert_allclose(got["nodes"], np.asarray(want["nodes"]), rtol=0, atol=1e-9)
        np.testing.assert_allclose(got["forces"], np.asarray(want["forces"]), rtol=1e-9,
                                   atol=1e-9 * np.abs(np.asarray(want["forces"])).max())
    assert want["status"] == "ok"


def test_the_demo_sequence_gives_sinew_tracks_nodes(tmp_path):
    """scripts/demo's own sequence (the same sinew-synth arguments: a thick cantilever, 40
    frames, clutter and an occluder), tracked by sinew-track and by sinew.Tracker frame by frame."""
    subprocess.run([os.path.join(BIN, "sinew-synth"), "--scenario", "cantilever", "--thickness",
                    "thick", "--frames", "40", "--lambda-max", "5", "--noise", "8", "--clutter",
                    "12", "--occluder", "12:15", "--out", str(tmp_path)],
                   check=True, capture_output=True)
    results = tmp_path / "results.jsonl"
    subprocess.run([os.path.join(BIN, "sinew-track"), "--input",
                    str(tmp_path / "frames/f_%04d.png"), "--init", str(tmp_path / "init.json"),
                    "--out", str(results)], check=True, capture_output=True)
    expected = [line for line in map(json.loads, open(results)) if "nodes" in line]
    assert len(expected) == 40
    tracker = sinew.Tracker(str(tmp_path / "init.json"))
    worst = 0.0
    for k, want in enumerate(expected):
        frame = cv2.imread(str(tmp_path / f"frames/f_{k:04d}.png"), cv2.IMREAD_GRAYSCALE)
        got = tracker.track(frame)
        assert got["status"] == want["status"], k
        worst = max(worst, float(np.abs(got["nodes"] - np.asarray(want["nodes"])).max()))
    assert worst <= 1e-9


def test_a_dict_init_is_the_file(sequence):
    out, expected, frames = sequence
    tracker = sinew.Tracker(json.load(open(out / "init.json")))
    got = tracker.track(frames[0])
    np.testing.assert_allclose(got["nodes"], np.asarray(expected[0]["nodes"]), rtol=0, atol=1e-9)


def test_track_video_yields_every_frame(sequence):
    out, expected, _ = sequence
    tracker = sinew.Tracker(str(out / "init.json"))
    results = list(sinew.track_video(tracker, str(out / "frames/f_%04d.png")))
    assert [r["frame"] for r in results] == list(range(len(expected)))
    np.testing.assert_allclose(results[-1]["nodes"], np.asarray(expected[-1]["nodes"]), rtol=0,
                               atol=1e-9)


def test_bad_input_raises_with_the_field_named(sequence):
    out, _, frames = sequence
    init = json.load(open(out / "init.json"))
    init["observation"] = "sideways"
    with pytest.raises(ValueError, match="observation"):
        sinew.Tracker(init)
    tracker = sinew.Tracker(str(out / "init.json"))
    with pytest.raises(ValueError, match="2-D uint8"):
        tracker.track(np.dstack([frames[0]] * 3))
    with pytest.raises(ValueError, match="cannot open"):
        list(sinew.track_video(tracker, str(out / "missing.mp4")))

"""sinew.track_batch against sinew-track --batch on two rendered whisker pads and a corrupt video:
the same summary rows (a pandas DataFrame), the same tables in the results folders, a second call
skipping the videos done, and a bad manifest raising ValueError.

Run by ctest (python_module) with PYTHONPATH=<build>/python and SINEW_BINARY_DIR=<build>.
"""
import json
import os
import subprocess

import pytest

import sinew

pandas = pytest.importorskip("pandas")  # scripts/setup installs Debian's python3-pandas

BIN = os.path.join(os.environ.get("SINEW_BINARY_DIR", "build/release"), "tools")


@pytest.fixture(scope="module")
def videos(tmp_path_factory):
    root = tmp_path_factory.mktemp("batch")
    for seed in (1, 2):
        subprocess.run([os.path.join(BIN, "sinew-synth"), "--scenario", "whisker-pad", "--frames",
                        "40", "--width", "320", "--height", "240", "--whiskers", "4", "--seed",
                        str(seed), "--out", str(root / f"pad{seed}")],
                       check=True, capture_output=True)
    (root / "corrupt.mp4").write_bytes(os.urandom(4096))
    return root


def manifest(root, out):
    return {"out": str(root / out), "options": {"face": "left"},
            "videos": [{"video": str(root / "pad1/frames/f_%04d.png"), "out": "pad1"},
                       {"video": str(root / "corrupt.mp4")},
                       {"video": str(root / "pad2/frames/f_%04d.png"), "out": "pad2",
                        "redetect": "lost"}]}


def test_summary_matches_sinew_track(videos):
    path = videos / "cli.json"
    path.write_text(json.dumps(manifest(videos, "cli")))
    cli = subprocess.run([os.path.join(BIN, "sinew-track"), "--batch", str(path), "--quiet"],
                         capture_output=True, text=True)
    assert cli.returncode == 1
    assert cli.stderr.count("sinew-track: ") == 1 and "corrupt.mp4" in cli.stderr
    want = pandas.read_csv(videos / "cli/summary.csv")

    got = sinew.track_batch(manifest(videos, "py"), jobs=2)
    assert isinstance(got, pandas.DataFrame)
    assert got.attrs["exit_status"] == 1
    assert list(got.columns) == list(want.columns)
    assert list(got["video"]) == list(want["video"])
    assert list(got["status"]) == ["tracked", want["status"][1], "tracked"]
    assert got["status"][1].startswith("failed: ")
    for column in ("frames", "whiskers", "lost_fraction", "contact_frames"):
        assert list(got[column]) == pytest.approx(list(want[column]), abs=1e-6), column
    assert got["frames"][0] == 40 and got["whiskers"][0] > 0
    # The same tables as the command line's, byte for byte.
    for name in ("pad1", "pad2"):
        assert (videos / "py" / name / "whiskers.csv").read_bytes() == \
            (videos / "cli" / name / "whiskers.csv").read_bytes()

    # Again: the videos done are skipped with their first figures, the corrupt one fails again.
    again = sinew.track_batch(str(videos / "cli.json"))
    assert list(again["status"][[0, 2]]) == ["done earlier", "done earlier"]
    assert list(again["wall_seconds"][[0, 2]]) == pytest.approx(list(want["wall_seconds"][[0, 2]]),
                                                                abs=1e-3)
    gathered = sinew.track_batch(manifest(videos, "py"), gather=True)
    assert list(gathered["frames"]) == list(got["frames"])


def test_bad_manifest_is_a_value_error(videos):
    with pytest.raises(ValueError, match="videos\\[0\\].*face"):
        sinew.track_batch({"videos": [{"video": str(videos / "corrupt.mp4"), "face": "up"}]})
    with pytest.raises(ValueError, match="names no video"):
        sinew.track_batch({"videos": []})
    with pytest.raises(TypeError):
        sinew.track_batch(42)

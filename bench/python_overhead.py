"""What the Python module adds per frame over the C++ tracking time: the Tracker.track call's wall
time minus its own latency_us, over N calls on a rendered 1024 x 768 cantilever sequence.
    PYTHONPATH=build/release/python python3 bench/python_overhead.py [N]
"""
import os
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np

import sinew


def main():
    calls = int(sys.argv[1]) if len(sys.argv) > 1 else 1000
    tools = os.path.join(os.environ.get("SINEW_BINARY_DIR", "build/release"), "tools")
    with tempfile.TemporaryDirectory() as out:
        subprocess.run([os.path.join(tools, "sinew-synth"), "--scenario", "cantilever", "--frames",
                        "40", "--out", out], check=True, capture_output=True)
        frames = [cv2.imread(os.path.join(out, f"frames/f_{k:04d}.png"), cv2.IMREAD_GRAYSCALE)
                  for k in range(40)]
        tracker = sinew.Tracker(os.path.join(out, "init.json"))
        added, latency = [], []
        for k in range(calls):
            frame = frames[min(k, len(frames) - 1)]
            start = time.perf_counter()
            result = tracker.track(frame)
            added.append((time.perf_counter() - start) * 1e6 - result["latency_us"])
            latency.append(result["latency_us"])
    added = np.asarray(added)
    print(f"{calls} calls on {frames[0].shape[1]} x {frames[0].shape[0]} frames: C++ tracking "
          f"median {np.median(latency):.1f} us; added by Python: median {np.median(added):.2f} us, "
          f"mean {added.mean():.2f}, p99 {np.percentile(added, 99):.2f}")


if __name__ == "__main__":
    main()

"""Sinew: physics-based deformation from images.

``sinew.Tracker(init)`` tracks a beam-like object (a whisker, an antenna, a needle) through grey
frames and recovers the forces that bend it; ``sinew.Whiskers(face=...)`` finds every whisker of a
video on its first frame and tracks them all with their mechanics and contacts;
``sinew.detect_whiskers(frame, face=...)`` finds them on one frame (with the traces it rejected);
``sinew.track_video(tracker, path)`` runs either over a video file frame by frame;
``sinew.simulate(beam)`` solves a beam's static equilibrium under loads;
``sinew.track_batch(manifest)`` tracks many whisker videos as ``sinew-track --batch`` does and
returns the summary table as a pandas DataFrame;
``sinew.register(case)`` registers a template to scan markers as sinew-register does (when the
offline library is built). See the
README's Python section.
"""
from ._sinew import Tracker, Whiskers, detect_whiskers, simulate  # noqa: F401

try:
    from ._sinew import register  # noqa: F401
except ImportError:  # built without offline/
    pass


def track_video(tracker, path):
    """Yields tracker.track(frame) for every frame of a video or image sequence (OpenCV reads it:
    a file, or a printf pattern such as ``frames/f_%04d.png``), converted to grey."""
    import cv2

    capture = cv2.VideoCapture(path)
    if not capture.isOpened():
        raise ValueError(f"{path}: cannot open")
    while True:
        ok, frame = capture.read()
        if not ok:
            return
        if frame.ndim == 3:
            frame = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        yield tracker.track(frame)


def track_batch(manifest, jobs=1, task=None, gather=False, quiet=True):
    """Tracks every video of a manifest as ``sinew-track --batch`` does (docs/whisker_batch.md):
    one results folder per video, videos already done skipped, ``jobs`` videos at once, each in a
    child process. ``manifest`` is a path to the JSON file or a dict of the same content (its
    relative names then relative to the current folder). ``task`` tracks one video alone (0-based);
    ``gather`` tracks nothing and reads the videos' results. Returns the summary table as a pandas
    DataFrame, one row per video (video, out, frames, whiskers, lost_fraction, contact_frames,
    wall_seconds, status), with the batch's exit status in ``.attrs["exit_status"]`` (0 all tracked,
    1 a video failed: its row's status says why). A bad manifest raises ValueError."""
    import json

    try:
        import pandas
    except ImportError as e:
        raise ImportError(
            "sinew.track_batch returns a pandas DataFrame: install pandas (scripts/setup installs "
            "Debian's python3-pandas; or pip install pandas)") from e
    from ._sinew_batch import track_batch as _track_batch

    if isinstance(manifest, dict):
        status, rows = _track_batch(None, json.dumps(manifest), jobs, task, gather, quiet)
    elif isinstance(manifest, (str, bytes)) or hasattr(manifest, "__fspath__"):
        import os

        status, rows = _track_batch(os.fsdecode(manifest), None, jobs, task, gather, quiet)
    else:
        raise TypeError("track_batch: manifest is a path to a JSON file or a dict")
    columns = ["video", "out", "frames", "whiskers", "lost_fraction", "contact_frames",
               "wall_seconds", "status"]
    table = pandas.DataFrame(rows, columns=columns)
    table.attrs["exit_status"] = status
    return table

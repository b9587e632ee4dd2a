"""Sinew: physics-based deformation from images.

``sinew.Tracker(init)`` tracks a beam-like object (a whisker, an antenna, a needle) through grey
frames and recovers the forces that bend it; ``sinew.Whiskers(face=...)`` finds every whisker of a
video on its first frame and tracks them all with their mechanics and contacts;
``sinew.detect_whiskers(frame, face=...)`` finds them on one frame (with the traces it rejected);
``sinew.track_video(tracker, path)`` runs either over a video file frame by frame;
``sinew.simulate(beam)`` solves a beam's static equilibrium under loads;
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

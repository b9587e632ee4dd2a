#!/usr/bin/env bash
# sinew-track --batch end to end (issue 50, item 2), small enough for every CI run:
#   1. renders four short whisker pads (sinew-synth, 320x240, 80 frames at 500 fps) and writes a
#      corrupt video, a manifest of the five (one with its own scale and physics) and a second one
#      into another results folder;
#   2. an uninterrupted run with --jobs 2: exit 1, a summary row per video (four tracked, the corrupt
#      one failed) and exactly one error line, naming the corrupt file;
#   3. the same batch with --jobs 1 killed with SIGKILL while a video is halfway, then run again:
#      the videos done before the kill are skipped, the one killed halfway is tracked again, and
#      every video's table (CSV) is byte-identical, its HDF5 file's datasets equal (with h5py) and
#      its JSON Lines identical but for the timings to the uninterrupted run's.
#
#   track_batch_test.sh SINEW_TRACK SINEW_SYNTH
set -euo pipefail
track=$(readlink -f "${1:?usage: track_batch_test.sh SINEW_TRACK SINEW_SYNTH}")
synth=$(readlink -f "${2:?usage: track_batch_test.sh SINEW_TRACK SINEW_SYNTH}")
work=$(mktemp -d /tmp/sinew_track_batch.XXXXXX)
batch_pid=""
cleanup() {
  [[ -n $batch_pid ]] && kill -9 "$batch_pid" 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT
field() {  # field FILE KEY: a value of a JSON file
  python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))[sys.argv[2]])' "$1" "$2"
}
say() { echo "track_batch_test: $*"; }
fail() {
  say "FAIL: $*"
  exit 1
}
cd "$work"

# ---- 1. inputs
for seed in 1 2 3 4; do
  "$synth" --scenario whisker-pad --frames 80 --width 320 --height 240 --whiskers 4 --seed "$seed" \
    --out "pad$seed" >/dev/null
done
head -c 4096 /dev/urandom >corrupt.mp4
manifest() {  # manifest RESULTS_FOLDER
  cat <<JSON
{"out": "$1", "options": {"face": "left"},
 "videos": [
  {"video": "pad1/frames/f_%04d.png", "out": "pad1"},
  {"video": "pad2/frames/f_%04d.png", "out": "pad2", "mm_per_px": 0.02, "whisker_preset": "rat-c2"},
  {"video": "corrupt.mp4"},
  {"video": "pad3/frames/f_%04d.png", "out": "pad3"},
  {"video": "pad4/frames/f_%04d.png", "out": "pad4", "redetect": "lost"}
 ]}
JSON
}
manifest reference >reference.json
manifest resumed >resumed.json

# ---- 2. uninterrupted
status=0
"$track" --batch reference.json --jobs 2 >reference.out 2>reference.err || status=$?
[[ $status == 1 ]] || fail "exit status $status with a corrupt video (want 1)"
rows=$(tail -n +2 reference/summary.csv | wc -l)
[[ $rows == 5 ]] || fail "summary.csv has $rows rows (want 5)"
[[ $(grep -c ',tracked$' reference/summary.csv) == 4 ]] || fail "not 4 videos tracked: $(cat reference/summary.csv)"
grep -q '^corrupt.mp4,.*,failed: ' reference/summary.csv || fail "the corrupt video's row: $(cat reference/summary.csv)"
errors=$(grep -c '^sinew-track: ' reference.err || true)
[[ $errors == 1 ]] || fail "$errors error lines (want 1): $(cat reference.err)"
grep -q '^sinew-track: corrupt.mp4: ' reference.err || fail "the error line does not name the file: $(cat reference.err)"
for v in pad1 pad2 pad3 pad4; do
  for f in results.jsonl whiskers.csv whiskers.h5 done.json; do
    [[ -s reference/$v/$f ]] || fail "reference/$v/$f missing"
  done
  frames=$(field "reference/$v/done.json" frames)
  [[ $frames == 80 ]] || fail "$v: $frames frames in done.json (want 80)"
done
grep -q '"m0_N_m"\|m0_N_m' reference/pad2/whiskers.csv || fail "pad2's scale did not reach its run (no SI columns)"
say "uninterrupted: 4 tracked, 1 failed in one line"

# ---- 3. SIGKILL while a video is halfway, then again
"$track" --batch resumed.json --jobs 1 >killed.out 2>killed.err &
batch_pid=$!
for _ in $(seq 2400); do  # up to 120 s for pad1 on a loaded machine
  [[ -f resumed/pad1/done.json && -f resumed/pad2/results.jsonl.tmp ]] && break
  kill -0 "$batch_pid" 2>/dev/null || fail "the batch ended before it could be killed"
  sleep 0.05
done
[[ -f resumed/pad2/results.jsonl.tmp ]] || fail "pad2 never started"
kill -9 "$batch_pid"
wait "$batch_pid" 2>/dev/null || true
batch_pid=""
sleep 0.3
[[ ! -f resumed/pad2/done.json ]] || fail "pad2 finished before the kill (the test needs it halfway)"
! pgrep -f "resumed.json" >/dev/null || fail "a child of the killed batch is still running"
say "killed with pad1 done and pad2 halfway"
status=0
"$track" --batch resumed.json --jobs 2 >rerun.out 2>rerun.err || status=$?
[[ $status == 1 ]] || fail "rerun exit status $status (want 1)"
grep -q '1 done earlier (skipped)' rerun.err || fail "the rerun did not skip pad1: $(head -n 1 rerun.err)"
grep -q '^pad1/frames/f_%04d.png,.*,done earlier$' resumed/summary.csv || fail "pad1 not skipped: $(cat resumed/summary.csv)"
strip_timings() {  # JSON Lines without the wall-clock fields
  python3 - "$1" <<'PY'
import json, sys
for line in open(sys.argv[1]):
    j = json.loads(line)
    j.pop("latency_us", None)
    j.get("detection", {}).pop("seconds", None)
    j.get("redetect", {}).pop("ms", None)
    print(json.dumps(j, sort_keys=True))
PY
}
h5_same() {  # every dataset of two HDF5 files equal (NaN = NaN); 77 without h5py
  /usr/bin/python3 - "$1" "$2" <<'PY'
import sys
try:
    import h5py
    import numpy as np
except ImportError:
    sys.exit(77)
a, b = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
names, other = [], []
a.visit(names.append)
b.visit(other.append)
same = names == other
for name in names:
    if same and isinstance(a[name], h5py.Dataset):
        x, y = a[name][()], b[name][()]
        if x.dtype.names:  # the summary table: field by field
            same = all(np.array_equal(x[f], y[f], equal_nan=x[f].dtype.kind == "f")
                       for f in x.dtype.names)
        else:
            same = np.array_equal(x, y, equal_nan=x.dtype.kind == "f")
sys.exit(0 if same else 1)
PY
}
for v in pad1 pad2 pad3 pad4; do
  cmp -s "reference/$v/whiskers.csv" "resumed/$v/whiskers.csv" || fail "$v: whiskers.csv differs from the uninterrupted run's"
  diff -q <(strip_timings "reference/$v/results.jsonl") <(strip_timings "resumed/$v/results.jsonl") >/dev/null ||
    fail "$v: results.jsonl differs from the uninterrupted run's (timings aside)"
  if h5_same "reference/$v/whiskers.h5" "resumed/$v/whiskers.h5"; then :; else
    status=$?
    ((status == 77)) || fail "$v: whiskers.h5 differs from the uninterrupted run's"
  fi
  for k in frames whiskers lost_fraction contact_frames; do
    [[ $(field "reference/$v/done.json" $k) == $(field "resumed/$v/done.json" $k) ]] ||
      fail "$v: $k differs in done.json"
  done
done
say "PASS: killed halfway and rerun: every table identical to the uninterrupted run's"

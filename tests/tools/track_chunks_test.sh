#!/usr/bin/env bash
# sinew-track --batch with a video tracked in chunks (issue 50, item 2), end to end:
#   1. renders two short whisker pads (sinew-synth, 320x240, 160 frames at 500 fps, seeds 1 and 2)
#      and tracks each twice in one batch (--jobs 2): in one pass, and as 2 chunks stitched;
#   2. scripts/whisker_chunk_check.py: on every frame the stitched results have the one pass's ids
#      with curves within 0.5 px (no border frame disagrees: N = 0 here), no whisker missing; the
#      stitched table has every frame and id once, and the HDF5 file every frame;
#   3. the video's done.json removed: a rerun only stitches again (its chunks are done) and
#      writes byte-identical results; a damaged line in a chunk's results fails that video with
#      the file and line named, the other videos stay done;
#   4. chunks with an overlay: the manifest is refused in one line naming "chunks".
#
#   track_chunks_test.sh SINEW_TRACK SINEW_SYNTH SOURCE_DIR
set -euo pipefail
usage="usage: track_chunks_test.sh SINEW_TRACK SINEW_SYNTH SOURCE_DIR"
track=$(readlink -f "${1:?$usage}")
synth=$(readlink -f "${2:?$usage}")
check=$(readlink -f "${3:?$usage}")/scripts/whisker_chunk_check.py
work=$(mktemp -d /tmp/sinew_track_chunks.XXXXXX)
trap 'rm -rf "$work"' EXIT
say() { echo "track_chunks_test: $*"; }
fail() {
  say "FAIL: $*"
  exit 1
}
cd "$work"

# ---- 1. one pass and 2 chunks of the same videos
for seed in 1 2; do
  "$synth" --scenario whisker-pad --frames 160 --width 320 --height 240 --whiskers 4 --seed "$seed" \
    --out "pad$seed" >/dev/null
done
cat >m.json <<'JSON'
{"out": "res", "options": {"face": "left"},
 "videos": [{"video": "pad1/frames/f_%04d.png", "out": "one1"},
            {"video": "pad1/frames/f_%04d.png", "out": "two1", "chunks": 2},
            {"video": "pad2/frames/f_%04d.png", "out": "one2"},
            {"video": "pad2/frames/f_%04d.png", "out": "two2", "chunks": 2}]}
JSON
"$track" --batch m.json --jobs 2 >run.out 2>run.err || fail "exit status $? ($(cat run.err))"
[[ $(grep -c ',tracked$' res/summary.csv) == 4 ]] || fail "not 4 tracked: $(cat res/summary.csv)"

# ---- 2. the stitched results against the one pass
for seed in 1 2; do
  python3 "$check" "res/one$seed/results.jsonl" "res/two$seed/results.jsonl" \
    --max-border-frames 0 --min-agreement 1.0 --max-missing 0.0 >"check$seed.out" ||
    fail "seed $seed: $(cat "check$seed.out")"
  say "seed $seed: $(tail -n 2 "check$seed.out" | tr '\n' ' ')"
  /usr/bin/python3 - "res/two$seed" <<'PY' || fail "seed $seed: the stitched table or HDF5 file"
import csv, sys
import h5py
d = sys.argv[1]
rows = list(csv.DictReader(open(f"{d}/whiskers.csv")))
keys = [(int(r["frame"]), int(r["id"])) for r in rows]
assert len(keys) == len(set(keys)), "a frame and id twice in the table"
frames = sorted({f for f, _ in keys})
assert frames == list(range(160)), f"frames {frames[0]}..{frames[-1]}, {len(frames)} of 160"
with h5py.File(f"{d}/whiskers.h5") as f:
    assert list(f["frame"][:]) == frames, "the HDF5 file's frames"
    assert len(f["summary"]) == len(rows), "the HDF5 summary's rows"
    assert "chunks" in f.attrs
PY
done

# ---- 3. resume: the chunks are done, only the stitching runs again
cp res/two1/results.jsonl first.jsonl
rm res/two1/done.json
"$track" --batch m.json >rerun.out 2>rerun.err || fail "rerun: exit status $?"
grep -q '(chunk [0-9]*)' rerun.err && fail "rerun tracked a chunk again: $(cat rerun.err)"
cmp -s first.jsonl res/two1/results.jsonl || fail "rerun's stitched results differ"
say "rerun: stitched again from the done chunks, identical results"

# ---- 3b. a damaged chunk's line is named (file and line) in the video's failed row, the others done
cp -r res/two1 keep_two1
sed -i '5s/.*/{"frame": 3, "whisk/' res/two1/chunk_1/results.jsonl
rm res/two1/done.json
status=0
"$track" --batch m.json >damaged.out 2>damaged.err || status=$?
[[ $status == 1 ]] || fail "a damaged chunk: exit status $status (want 1)"
grep -q 'chunk_1/results.jsonl:5: not JSON' res/summary.csv ||
  fail "the damaged chunk's file and line not in the summary: $(cat res/summary.csv)"
[[ $(grep -c ',done earlier$' res/summary.csv) == 3 ]] || fail "not 3 done beside it: $(cat res/summary.csv)"
rm -rf res/two1 && mv keep_two1 res/two1
say "damaged chunk: $(grep -o 'chunk_1/results.jsonl:5: not JSON' res/summary.csv)"

# ---- 4. chunks with an overlay are refused
sed 's/"chunks": 2}/"chunks": 2, "overlay": true}/' m.json >bad.json
status=0
"$track" --batch bad.json >bad.out 2>bad.err || status=$?
[[ $status == 2 ]] || fail "chunks with an overlay: exit status $status (want 2)"
grep -q 'chunks' bad.err || fail "the error does not say why: $(cat bad.err)"
say "chunks with an overlay refused: $(head -n 1 bad.err)"
say "PASS"

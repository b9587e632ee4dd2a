#!/usr/bin/env bash
# sinew-track --batch under a real Slurm job array (issue 50, item 3):
#   1-2. a single-node Slurm on localhost (slurm_cluster.sh: packages, daemons, all files in a
#      temporary folder);
#   3. renders two short whisker pads (sinew-synth, 320x240, 60 frames), writes a corrupt video and
#      a manifest of the three, and submits examples/slurm/track_array.sbatch as a job array (one
#      task per video) and the gather job after it (--dependency=afterany);
#   4. waits for both to leave the queue and checks: the two pads' tasks COMPLETED with their
#      results, the corrupt video's task FAILED with one line naming the file, and the gathered
#      summary.csv has three rows (two tracked, one failed);
#   5. stops the daemons it started (trap on exit) and removes the folder.
#
#   track_slurm_array_test.sh SINEW_TRACK SINEW_SYNTH SBATCH_SCRIPT
#
# Exit status: 0 passed, 1 failed, 77 skipped (not root, or the packages cannot be installed).
# Registered with ctest under the label "slurm" (ctest -L slurm).
set -euo pipefail

usage="usage: track_slurm_array_test.sh SINEW_TRACK SINEW_SYNTH SBATCH_SCRIPT"
tool=${1:?$usage}
synth=$(readlink -f "${2:?$usage}")
sbatch_script=${3:?$usage}
# shellcheck source=slurm_cluster.sh
source "$(dirname "$0")/slurm_cluster.sh"
mkdir -p "$work"/videos

# ---- 3. two quick pads, a corrupt file and their manifest (paths relative to it)
for seed in 1 2; do
  "$synth" --scenario whisker-pad --frames 60 --width 320 --height 240 --whiskers 4 --seed "$seed" \
    --out "$work/videos/pad$seed" >/dev/null
done
head -c 4096 /dev/urandom >"$work/videos/corrupt.mp4"
cat >"$work/manifest.json" <<JSON
{"out": "results", "options": {"face": "left"},
 "videos": [
  {"video": "videos/pad1/frames/f_%04d.png", "out": "pad1"},
  {"video": "videos/corrupt.mp4"},
  {"video": "videos/pad2/frames/f_%04d.png", "out": "pad2", "mm_per_px": 0.02,
   "whisker_preset": "rat-c2"}
 ]}
JSON
n=$("$tool" --batch "$work/manifest.json" --list | wc -l)
[[ $n == 3 ]] || fail "--list gives $n videos (want 3)"

# ---- 4. the array, one task per video, then the gather job, from another folder than the manifest's
cd /
job=$(SINEW_TRACK=$tool sbatch --parsable --array=0-$((n - 1)) --cpus-per-task=1 \
  --output="$work/log/task_%a.out" "$sbatch_script" "$work/manifest.json") ||
  fail "sbatch failed"
job=${job%%;*}
gather=$(SINEW_TRACK=$tool sbatch --parsable --dependency="afterany:$job" --cpus-per-task=1 \
  --output="$work/log/gather.out" "$sbatch_script" "$work/manifest.json" --gather) ||
  fail "sbatch (gather) failed"
gather=${gather%%;*}
say "submitted job array $job ($n tasks) and gather job $gather after $(elapsed)"
wait_for_array "$job" 600
job=$gather
wait_for_array "$gather" 300

completed=$(grep -c "JobState=COMPLETED" "$work/log/jobcomp.txt" 2>/dev/null || true)
failed=$(grep -c "JobState=FAILED" "$work/log/jobcomp.txt" 2>/dev/null || true)
check "2 tasks COMPLETED (got ${completed:-0})" test "${completed:-0}" -eq 2
# The corrupt video's task (exit 2) and the gather job (exit 1: a video failed).
check "2 jobs FAILED (got ${failed:-0})" test "${failed:-0}" -eq 2
for i in 0 2; do
  name=pad$((i / 2 + 1))
  log=$work/log/task_$i.out
  check "task $i log exists" test -f "$log"
  check "task $i tracked its video alone" grep -q "1 of 1 video tracked" "$log"
  for f in results.jsonl whiskers.csv whiskers.h5 done.json; do
    check "results/$name/$f exists" test -s "$work/results/$name/$f"
  done
done
check "task 1 names the corrupt file and the reason" \
  grep -q "^sinew-track: .*videos/corrupt.mp4: cannot open" "$work/log/task_1.out"
check "task 1 printed one error line" test "$(grep -c '^sinew-track: ' "$work/log/task_1.out")" -eq 1
summary=$work/results/summary.csv
check "the gather job wrote summary.csv" test -s "$summary"
check "summary.csv: 3 rows" test "$(tail -n +2 "$summary" 2>/dev/null | wc -l)" -eq 3
check "summary.csv: 2 done" test "$(grep -c ',done earlier$' "$summary" 2>/dev/null)" -eq 2
check "summary.csv: the corrupt video failed" grep -q 'corrupt.mp4,.*,failed: cannot open' "$summary"
check "pad2's scale reached its run" grep -q m0_N_m "$work/results/pad2/whiskers.csv"
if ((failures > 0)); then
  for f in "$work"/log/task_*.out "$work/log/gather.out"; do
    echo "---- $f"
    cat "$f" 2>/dev/null || true
  done
  fail "$failures check(s) failed"
fi
say "PASS: $n array tasks and the gather job ($(elapsed))"

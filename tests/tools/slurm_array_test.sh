#!/usr/bin/env bash
# sinew-register under a real Slurm job array (issue 7, scope item 7):
#   1-2. a single-node Slurm on localhost (slurm_cluster.sh: packages, daemons, all files in a
#      temporary folder);
#   3. writes three quick cases (sinew-register --make-demo-case, with all / a third / every other
#      ICP marker) and a manifest, submits examples/slurm/register_array.sbatch as a job array;
#   4. waits for the array to leave the queue and checks each case's outputs and each task's log;
#   5. stops the daemons it started (trap on exit) and removes the folder.
#
#   slurm_array_test.sh SINEW_REGISTER SBATCH_SCRIPT
#
# Exit status: 0 passed, 1 failed, 77 skipped (ctest SKIP_RETURN_CODE: not root, or the packages
# cannot be installed). Registered with ctest under the label "slurm" (ctest -L slurm).
set -euo pipefail

tool=${1:?usage: slurm_array_test.sh SINEW_REGISTER SBATCH_SCRIPT}
sbatch_script=${2:?usage: slurm_array_test.sh SINEW_REGISTER SBATCH_SCRIPT}
# shellcheck source=slurm_cluster.sh
source "$(dirname "$0")/slurm_cluster.sh"
mkdir -p "$work"/{cases,results}

# ---- 3. three quick cases and their manifest (paths relative to it)
"$tool" --make-demo-case "$work/cases/all" --quiet
markers=$(($(wc -l <"$work/cases/all/markers.csv") - 1))
for name in third every_other; do
  mkdir -p "$work/cases/$name"
  cp "$work/cases/all"/{template.obj,attachments.json,case.json} "$work/cases/$name/"
done
# The same capsule with fewer ICP markers: the header and the first third / every other one.
head -n $((1 + markers / 3)) "$work/cases/all/markers.csv" >"$work/cases/third/markers.csv"
awk 'NR == 1 || NR % 2 == 0' "$work/cases/all/markers.csv" >"$work/cases/every_other/markers.csv"
cat >"$work/manifest.json" <<EOF
{"cases": [
  {"case": "cases/all/case.json", "out": "results/all", "truth": "cases/all/truth_surface.obj"},
  {"case": "cases/third/case.json", "out": "results/third"},
  {"case": "cases/every_other/case.json", "out": "results/every_other"}
]}
EOF
names=(all third every_other)

# ---- 4. the array, one task per case, from another folder than the manifest's
cd /
job=$(SINEW_REGISTER=$tool sbatch --parsable --array=0-2 --cpus-per-task=1 \
  --output="$work/log/task_%a.out" "$sbatch_script" "$work/manifest.json") ||
  fail "sbatch failed"
job=${job%%;*}
say "submitted job array $job (3 tasks) after $(elapsed)"
wait_for_array "$job" 900

completed=$(grep -c "JobState=COMPLETED" "$work/log/jobcomp.txt" 2>/dev/null || true)
check "3 tasks COMPLETED in the job completion log (got ${completed:-0})" test "${completed:-0}" -eq 3
for i in 0 1 2; do
  out=$work/results/${names[i]}
  log=$work/log/task_$i.out
  check "task $i log exists" test -f "$log"
  check "task $i ran case $i alone" grep -q "== case $i of 3 " "$log"
  check "task $i ran no other case" test "$(grep -c "^== case " "$log" 2>/dev/null)" -eq 1
  check "task $i registered its case" grep -q "1 of 1 case registered, 0 failed" "$log"
  for f in result_surface.obj result.vtu report.json; do
    check "$out/$f exists" test -s "$out/$f"
  done
  check "$out/report.json has a termination reason" \
    grep -Eq '"termination": "[a-z-]+"' \
    "$out/report.json"
  check "$out/result.vtu is complete" grep -q "</VTKFile>" "$out/result.vtu"
done
check "case 0 compared with its truth" grep -q '"truth"' "$work/results/all/report.json"
if ((failures > 0)); then
  for i in 0 1 2; do
    echo "---- task $i output"
    cat "$work/log/task_$i.out" 2>/dev/null || true
  done
  fail "$failures check(s) failed"
fi
say "PASS: 3 array tasks, every case's outputs present ($(elapsed))"

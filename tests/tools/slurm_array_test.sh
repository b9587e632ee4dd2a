#!/usr/bin/env bash
# sinew-register under a real Slurm job array (issue 7, scope item 7):
#   1. installs Debian's slurm-wlm and munge when missing (apt-get, root only);
#   2. starts munged, slurmctld and slurmd for a single node on localhost, with every file
#      (config, key, socket, state, logs) in a temporary folder;
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

readonly SKIP=77
tool=${1:?usage: slurm_array_test.sh SINEW_REGISTER SBATCH_SCRIPT}
sbatch_script=${2:?usage: slurm_array_test.sh SINEW_REGISTER SBATCH_SCRIPT}
tool=$(readlink -f "$tool")
sbatch_script=$(readlink -f "$sbatch_script")
start=$(date +%s)

say() { echo "slurm_array_test: $*"; }
skip() {
  say "SKIP: $*"
  exit "$SKIP"
}
fail() {
  say "FAIL: $*"
  exit 1
}
elapsed() { echo "$(($(date +%s) - start)) s"; }

[[ -x $tool ]] || fail "$tool is not an executable"
[[ -f $sbatch_script ]] || fail "$sbatch_script not found"

# ---- 1. packages
installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
packages=(slurm-wlm munge)
missing=()
for p in slurmctld slurmd slurm-client munge; do installed "$p" || missing+=("$p"); done
if ((${#missing[@]} > 0)); then
  [[ $(id -u) == 0 ]] || skip "Slurm packages missing (${missing[*]}) and not root to install them"
  command -v apt-get >/dev/null || skip "Slurm packages missing and no apt-get"
  say "installing ${packages[*]} (missing: ${missing[*]})"
  export DEBIAN_FRONTEND=noninteractive
  if ! timeout 900 apt-get install -y -q --no-install-recommends "${packages[@]}" >/dev/null; then
    timeout 300 apt-get update -q >/dev/null || true
    timeout 900 apt-get install -y -q --no-install-recommends "${packages[@]}" >/dev/null ||
      skip "apt-get cannot install ${packages[*]}"
  fi
  say "installed in $(elapsed)"
fi
[[ $(id -u) == 0 ]] || skip "not root: slurmd must run as root to start jobs"
for c in munged slurmctld slurmd sbatch squeue sinfo scontrol; do
  command -v "$c" >/dev/null || skip "$c not found after installing ${packages[*]}"
done

# ---- 2. daemons, all files in one folder
work=$(mktemp -d /tmp/sinew_slurm_test.XXXXXX)
chmod 700 "$work"
mkdir -p "$work"/{munge,state,spool,log,run,cases,results}
pids=()  # every daemon started here, stopped by pid on exit
job=""
cleanup() {
  local status=$?
  if [[ -n $job ]] && [[ -n $(squeue -h -j "$job" 2>/dev/null) ]]; then
    scancel "$job" 2>/dev/null || true  # its steps end before the daemons that run them
    for _ in $(seq 30); do [[ -z $(squeue -h -j "$job" 2>/dev/null) ]] && break; sleep 1; done
  fi
  for ((i = ${#pids[@]} - 1; i >= 0; --i)); do kill "${pids[i]}" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null || true
  done
  if ((status != 0 && status != SKIP)); then
    for f in "$work"/log/*; do
      [[ -f $f ]] || continue
      echo "---- $f (last 40 lines)"
      tail -n 40 "$f"
    done
  fi
  rm -rf "$work"
  say "finished after $(elapsed)"
  exit "$status"
}
trap cleanup EXIT

# A random port pair, so that a system Slurm or a second run of this test does not collide.
ctld_port=$((20000 + RANDOM % 20000))
slurmd_port=$((ctld_port + 1))
socket=$work/munge/munge.socket

dd if=/dev/urandom of="$work/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$work/munge/munge.key"
munged --foreground --force --key-file="$work/munge/munge.key" --socket="$socket" \
  --pid-file="$work/run/munged.pid" --log-file="$work/log/munged.log" \
  --seed-file="$work/munge/munged.seed" >"$work/log/munged.out" 2>&1 &
pids+=($!)
for _ in $(seq 100); do [[ -S $socket ]] && break; sleep 0.1; done
[[ -S $socket ]] || fail "munged did not create its socket"
munge --socket="$socket" -n | unmunge --socket="$socket" >/dev/null || fail "munge round trip"

cpus=$(nproc)
memory=$(($(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 / 2))
conf=$work/slurm.conf
cat >"$conf" <<EOF
ClusterName=sinewtest
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$socket
CredType=cred/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/run/slurmctld.pid
SlurmdPidFile=$work/run/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$work/log/jobcomp.txt
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
SlurmdTimeout=60
InactiveLimit=0
KillWait=5
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$memory State=UNKNOWN
PartitionName=sinew Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF=$conf

slurmctld -D -i -f "$conf" >"$work/log/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -N localhost -f "$conf" >"$work/log/slurmd.out" 2>&1 &
pids+=($!)
state=""
for _ in $(seq 120); do
  state=$(sinfo -h -n localhost -o %T 2>/dev/null || true)
  [[ $state == idle ]] && break
  for pid in "${pids[@]}"; do kill -0 "$pid" 2>/dev/null || fail "a daemon exited (pid $pid)"; done
  sleep 0.5
done
[[ $state == idle ]] || fail "the node did not become idle (state '$state')"
say "munged, slurmctld and slurmd up on ports $ctld_port/$slurmd_port after $(elapsed)"

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
deadline=$(($(date +%s) + 900))
while [[ -n $(squeue -h -j "$job" 2>/dev/null) ]]; do
  (($(date +%s) < deadline)) || fail "job $job still queued or running after 900 s: $(squeue -j "$job")"
  sleep 2
done
say "job array $job left the queue after $(elapsed)"

failures=0
check() {  # check CONDITION-COMMAND... ; counts a failure with a message
  local what=$1
  shift
  if ! "$@"; then
    say "FAIL: $what"
    failures=$((failures + 1))
  fi
}
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

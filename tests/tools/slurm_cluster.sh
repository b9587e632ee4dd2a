# A single-node Slurm on localhost for the job-array tests (sourced, not run), shared by
# slurm_array_test.sh (sinew-register) and track_slurm_array_test.sh (sinew-track):
#   1. installs Debian's slurm-wlm and munge when missing (apt-get, root only);
#   2. starts munged, slurmctld and slurmd for a single node on localhost, with every file
#      (config, key, socket, state, logs) in a temporary folder $work (subfolders log/, and the
#      caller's own), stopped and removed on exit (trap);
#   3. wait_for_array JOB SECONDS waits for a job array to leave the queue; check WHAT CMD...
#      counts failed checks in $failures.
# The caller sets tool and sbatch_script (checked to exist) before sourcing; skip() exits 77
# (ctest SKIP_RETURN_CODE: not root, or the packages cannot be installed).
readonly SKIP=77
tool=$(readlink -f "$tool")
sbatch_script=$(readlink -f "$sbatch_script")
start=$(date +%s)

say() { echo "$(basename "$0" .sh): $*"; }
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
mkdir -p "$work"/{munge,state,spool,log,run}
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

wait_for_array() {  # wait_for_array JOB SECONDS
  local deadline=$(($(date +%s) + $2))
  while [[ -n $(squeue -h -j "$1" 2>/dev/null) ]]; do
    (($(date +%s) < deadline)) || fail "job $1 still queued or running after $2 s: $(squeue -j "$1")"
    sleep 2
  done
  say "job array $1 left the queue after $(elapsed)"
}

failures=0
check() {  # check WHAT COMMAND... ; counts a failure with a message
  local what=$1
  shift
  if ! "$@"; then
    say "FAIL: $what"
    failures=$((failures + 1))
  fi
}

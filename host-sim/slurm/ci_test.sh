#!/bin/bash
# The Slurm test of `cargo xtask test`: a one-node Slurm cluster on localhost flies a
# small campaign as a 4-task job array (campaign.sbatch), the shards are merged, and the
# merged campaign.csv and summary.json must be byte-identical to a single-process run.
#
#   host-sim/slurm/ci_test.sh PARAPET_BINARY [CAMPAIGN]    (as root)
#
# Installs Debian's slurmctld, slurmd and munge when missing (apt-get), runs a private
# munged (own key and socket) and both Slurm daemons with a minimal slurm.conf in a
# temporary directory, and stops them at the end, also on failure. Every wait has a
# timeout (TIMEOUT_S, default 300 s for the array).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
parapet=$(realpath "${1:?usage: ci_test.sh PARAPET_BINARY [CAMPAIGN]}")
campaign=$(realpath "${2:-$here/../../scenes/campaigns/slurm_ci.toml}")
timeout_s=${TIMEOUT_S:-300}

if [ "$(id -u)" -ne 0 ]; then echo "ci_test.sh: needs root (daemons, apt-get)" >&2; exit 1; fi
if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v munged >/dev/null \
    || ! command -v sbatch >/dev/null; then
    echo "== installing slurmctld slurmd munge (apt-get)"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq slurmctld slurmd slurm-client munge >/dev/null
fi

work=$(mktemp -d /tmp/parapet-slurm.XXXXXX)
pids=()
cleanup() {
    status=$?
    # Our cluster's jobs first (SLURM_CONF is the private one), then the daemons we started.
    if [ -n "${SLURM_CONF:-}" ]; then timeout 10 scancel --quiet --user=root 2>/dev/null || true; fi
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    for p in "${pids[@]}"; do wait "$p" 2>/dev/null || true; done
    if [ "$status" -ne 0 ]; then
        echo "== ci_test.sh failed ($status); daemon logs:" >&2
        tail -n 30 "$work"/*.log >&2 2>/dev/null || true
    fi
    rm -rf "$work"
    exit "$status"
}
trap cleanup EXIT INT TERM

# A private munge daemon: own key, socket, pid and log.
dd if=/dev/urandom of="$work/munge.key" bs=1024 count=1 status=none
chmod 400 "$work/munge.key"
mkdir -p "$work/munge"
chmod 700 "$work/munge"
munged --force --foreground --key-file="$work/munge.key" --socket="$work/munge/munge.socket" \
    --pid-file="$work/munge/munged.pid" --seed-file="$work/munge/seed" \
    --log-file="$work/munged.log" >>"$work/munged.log" 2>&1 &
pids+=($!)
for _ in $(seq 50); do [ -S "$work/munge/munge.socket" ] && break; sleep 0.1; done
[ -S "$work/munge/munge.socket" ] || { echo "munged did not start" >&2; exit 1; }

node=$(hostname -s)
mkdir -p "$work/state" "$work/spool" "$work/out"
cat > "$work/slurm.conf" <<CONF
ClusterName=parapetci
SlurmctldHost=$node(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$work/munge/munge.socket
SlurmctldPort=$((20000 + RANDOM % 20000))
SlurmdPort=$((40000 + RANDOM % 20000))
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
ReturnToService=2
NodeName=$node NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=ci Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$work/slurm.conf"
slurmctld -D -f "$SLURM_CONF" >>"$work/slurmctld.log" 2>&1 &
pids+=($!)
slurmd -D -f "$SLURM_CONF" -N "$node" >>"$work/slurmd.log" 2>&1 &
pids+=($!)
echo "== waiting for the node"
for _ in $(seq 100); do
    state=$(sinfo -h -N -o '%t' 2>/dev/null | head -n1 || true)
    case "$state" in idle*|mix*|alloc*) break ;; esac
    sleep 0.2
done
sinfo -N
case "$(sinfo -h -N -o '%t' | head -n1)" in idle*|mix*|alloc*) ;; *) echo "the node did not come up" >&2; exit 1 ;; esac

echo "== sbatch --array=1-4 (timeout ${timeout_s} s)"
start=$(date +%s)
timeout "$timeout_s" sbatch --wait --array=1-4 --cpus-per-task=1 --chdir="$work/out" \
    --export=ALL,PARAPET="$parapet",CAMPAIGN="$campaign",OUT="$work/out" \
    "$here/campaign.sbatch"
echo "   array done in $(( $(date +%s) - start )) s"
for k in 1 2 3 4; do [ -f "$work/out/shard_$k/shard.json" ] || { echo "shard $k missing" >&2; cat "$work"/out/*.out >&2; exit 1; }; done
"$parapet" campaign-merge --campaign "$campaign" --out "$work/merged" "$work"/out/shard_{1,2,3,4}
"$parapet" campaign "$campaign" --jobs 2 --out "$work/single"
for f in campaign.csv summary.json; do
    cmp "$work/merged/$f" "$work/single/$f"
done
echo "== Slurm test passed: the 4-task array merged is byte-identical to the single-process run"

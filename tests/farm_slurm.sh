#!/usr/bin/env bash
# The Slurm recipes for real (scripts/farm/, issue 14 item 4): starts munged
# and a single-node Slurm (slurmctld + slurmd, generated slurm.conf,
# everything in a temp folder, free ports), submits a 3-frame array job of a
# tiny scene (slurm_frames.sbatch) and checks the three frames open; then one
# frame as 3 photon shards with a dependent merge job (slurm_shards) and
# checks the merge ran after the shards and equals a bake on one machine (the
# grids' checksums); waits at most 120 s for each, and shuts everything down. Exit 77 (skipped) without slurm-wlm/munge or root.
# Usage: farm_slurm.sh BAKER SOURCE_DIR WORKDIR
set -u
BAKER=$1 SRC=$2 WORK=$3
for t in slurmctld slurmd sbatch squeue munged vdb_print python3; do
  command -v $t >/dev/null || [ -x /usr/sbin/$t ] ||
    { echo "SKIP: $t not found (apt-get install slurm-wlm munge)"; exit 77; }
done
[ "$(id -u)" = 0 ] || { echo "SKIP: a private Slurm needs root (slurmd runs jobs as their user)"; exit 77; }
export PATH=$PATH:/usr/sbin
fail() { echo "FAIL: $*"; for l in "$WORK"/log/*.log; do echo "== $l"; tail -5 "$l"; done; exit 1; }
rm -rf "$WORK" && mkdir -p "$WORK"/{munge,state,spool,log,job} && cd "$WORK" || exit 1
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null; done
  sleep 0.5
  for p in "${PIDS[@]}"; do kill -9 "$p" 2>/dev/null; done
}
trap cleanup EXIT

# munge: its own key, socket and files
dd if=/dev/urandom of=munge/munge.key bs=1024 count=1 2>/dev/null && chmod 600 munge/munge.key
munged --foreground --force --key-file="$WORK/munge/munge.key" --socket="$WORK/munge/sock" \
  --pid-file="$WORK/munge/pid" --log-file="$WORK/log/munged.log" --seed-file="$WORK/munge/seed" &
PIDS+=($!)

read -r P1 P2 < <(python3 -c 'import socket
s=[socket.socket() for _ in range(2)]
[x.bind(("127.0.0.1",0)) for x in s]
print(*[x.getsockname()[1] for x in s])')
node=$(slurmd -C | head -1 | sed 's/^NodeName=[^ ]*/NodeName=localhost NodeAddr=127.0.0.1/; s/ UpTime=.*//')
cat > slurm.conf <<CONF
ClusterName=bakertest
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$P1
SlurmdPort=$P2
SlurmUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$WORK/munge/sock
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
StateSaveLocation=$WORK/state
SlurmdSpoolDir=$WORK/spool
SlurmctldPidFile=$WORK/state/slurmctld.pid
SlurmdPidFile=$WORK/spool/slurmd.pid
SlurmctldLogFile=$WORK/log/slurmctld.log
SlurmdLogFile=$WORK/log/slurmd.log
$node State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$WORK/slurm.conf
for i in $(seq 50); do [ -S munge/sock ] && break; sleep 0.1; done
[ -S munge/sock ] || fail "munged did not start"
slurmctld -D -i -f "$SLURM_CONF" > log/slurmctld.out 2>&1 &
PIDS+=($!)
slurmd -D -N localhost -f "$SLURM_CONF" > log/slurmd.out 2>&1 &
PIDS+=($!)
for i in $(seq 100); do sinfo -h -o %T 2>/dev/null | grep -Eq '^(idle|mixed)' && break; sleep 0.2; done
sinfo -h -o %T | grep -Eq '^(idle|mixed)' || fail "the node did not come up: $(sinfo 2>&1)"

sed "s|\"resolution\": 128|\"resolution\": 16|; s|meshes/|$SRC/scenes/meshes/|" "$SRC/scenes/cube.json" > job/scene.json
job=$(cd job && BAKER=$BAKER BAKER_CACHE_DIR=$WORK/kcache sbatch --parsable --array=1-3 \
  --output="$WORK/job/task-%a.out" "$SRC/scripts/farm/slurm_frames.sbatch" scene.json 'out.####.vdb' \
  --photons 1000 -q) || fail "sbatch failed"
echo "submitted array job $job"
for i in $(seq 600); do
  [ -z "$(squeue -h -j "$job" 2>/dev/null)" ] && break
  sleep 0.2
done
[ -z "$(squeue -h -j "$job")" ] && [ $i -lt 600 ] || fail "job $job still running after 120 s: $(squeue)"
for f in 1 2 3; do
  v=job/out.000$f.vdb
  [ -s $v ] || { cat job/task-$f.out; fail "task $f wrote no $v"; }
  vdb_print -m $v | grep -q "frame: $f" || fail "$v does not open as frame $f"
done
echo "slurm: 3 array tasks baked 3 frames"

# one frame in 3 shards and a merge that waits for them (afterok)
ids=$(cd job && BAKER=$BAKER BAKER_CACHE_DIR=$WORK/kcache SBATCH_SHARD_OPTS="--output=$WORK/job/shard-%a.out" \
  SBATCH_MERGE_OPTS="--output=$WORK/job/merge.out" "$SRC/scripts/farm/slurm_shards" 3 scene.json merged.vdb \
  --photons 3001 -q) || fail "slurm_shards failed"
echo "submitted: $ids"
read -r _ sjob _ mjob <<<"$ids"
# the merge waits on the shards (a merge run early would find no shard files and fail)
scontrol show job "$mjob" | grep -o 'Dependency=[^ ]*' || true
for i in $(seq 600); do
  [ -z "$(squeue -h -j "$sjob,$mjob" 2>/dev/null)" ] && break
  sleep 0.2
done
[ -z "$(squeue -h -j "$sjob,$mjob")" ] || fail "jobs $sjob/$mjob still queued after 120 s: $(squeue)"
[ -s job/merged.vdb ] || { cat job/shard-*.out job/merge.out; fail "the merge job wrote no merged.vdb"; }
ls job/merged.shard-* >/dev/null 2>&1 && fail "the merge job left its shards"
(cd job && BAKER_CACHE_DIR=$WORK/kcache "$BAKER" bake scene.json -o single.vdb --photons 3001 -q) || fail "single bake failed"
sums() { vdb_print -m "$1" | grep -E '^(checksum_[a-z_]+|photon_count|bake_settings):' | grep -v checksum_box; }
[ "$(sums job/merged.vdb)" = "$(sums job/single.vdb)" ] ||
  fail "merged and single bake differ: $(diff <(sums job/merged.vdb) <(sums job/single.vdb))"
vdb_print -m job/merged.vdb | grep -q "merged_shard_count: 3" || fail "merged.vdb does not record 3 shards"
echo "slurm: 3 shard tasks and a dependent merge job = the single bake (grid checksums equal)"

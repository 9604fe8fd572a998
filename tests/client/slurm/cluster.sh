#!/bin/bash
# A single-node Slurm cluster on 127.0.0.1 from Debian's packages (slurmctld, slurmd, munge), every file
# of it in DIR: a munge key and socket, slurm.conf and cgroup.conf, state, spool, logs and pid files. No
# system configuration is read or written (clients find it through SLURM_CONF=DIR/slurm.conf).
#   cluster.sh start DIR   starts munged, slurmctld and slurmd; exits 0 once the node is idle, 3 when the
#                          daemons cannot run here (the reason on stderr), 1 on another failure
#   cluster.sh stop DIR    cancels what is left and stops the daemons (by their pid files)
# Daemons run as root (SlurmUser=root): Slurm's own daemons need it to launch jobs.
set -uo pipefail
cmd=${1:-}
T=${2:-}
[[ -n $cmd && -n $T ]] || { echo "usage: $0 start|stop DIR" >&2; exit 1; }

cannot() { echo "slurm cluster: $*" >&2; exit 3; }

stop() {
  export SLURM_CONF=$T/slurm.conf
  if [[ -f $T/slurm.conf ]]; then scancel --quiet --user=root >/dev/null 2>&1 || true; fi
  for name in slurmd slurmctld munged; do
    local pid_file=$T/$name.pid
    [[ -f $pid_file ]] || continue
    local pid
    pid=$(cat "$pid_file" 2>/dev/null) || continue
    [[ -n $pid ]] || continue
    kill -TERM "$pid" 2>/dev/null || continue
    # slurmd takes up to ~10 s to exit when slurmctld is gone; then KILL.
    for _ in $(seq 1 150); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
  done
}

if [[ $cmd == stop ]]; then stop; exit 0; fi
[[ $cmd == start ]] || { echo "usage: $0 start|stop DIR" >&2; exit 1; }

for tool in munged mungekey slurmctld slurmd sinfo sbatch; do
  command -v "$tool" >/dev/null || cannot "'$tool' is not installed (Debian: slurmctld slurmd slurm-client munge)"
done
[[ $(id -u) == 0 ]] || cannot "the daemons must run as root (this is uid $(id -u))"

mkdir -p "$T"/{state,spool,log}
chmod 755 "$T"  # munge clients reach the socket through every directory above it

# munge: a key of our own and a socket in DIR.
mungekey -c -k "$T/munge.key" 2>"$T/log/mungekey.log" || cannot "mungekey failed: $(cat "$T/log/mungekey.log")"
chmod 600 "$T/munge.key"
munged -F --socket="$T/munge.socket" --key-file="$T/munge.key" --pid-file="$T/munged.pid.own" \
  --seed-file="$T/munge.seed" --log-file="$T/log/munged.log" 2>>"$T/log/munged.log" &
echo $! > "$T/munged.pid"
for _ in $(seq 1 100); do [[ -S $T/munge.socket ]] && break; sleep 0.05; done
munge -S "$T/munge.socket" -n 2>/dev/null | unmunge -S "$T/munge.socket" >/dev/null 2>&1 ||
  { stop; cannot "munged did not start: $(tail -3 "$T/log/munged.log")"; }

# Ports away from a system Slurm's 6817/6818.
ctld_port=${MOREAU_SLURMCTLD_PORT:-26817}
slurmd_port=$((ctld_port + 1))
hardware=$(slurmd -C 2>/dev/null | head -1 | sed -e 's/^NodeName=[^ ]* //' -e 's/ *$//')
[[ -n $hardware ]] || { stop; cannot "slurmd -C gave no hardware line"; }
cat > "$T/slurm.conf" <<CONF
ClusterName=moreau-test
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$T/munge.socket
StateSaveLocation=$T/state
SlurmdSpoolDir=$T/spool
SlurmctldPidFile=$T/slurmctld.pid
SlurmdPidFile=$T/slurmd.pid
SlurmctldLogFile=$T/log/slurmctld.log
SlurmdLogFile=$T/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerParameters=batch_sched_delay=0,sched_interval=1,bf_interval=1
DependencyParameters=kill_invalid_depend
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
MailProg=/bin/true
NodeName=localhost NodeAddr=127.0.0.1 $hardware State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
echo "CgroupPlugin=cgroup/v1" > "$T/cgroup.conf"

export SLURM_CONF=$T/slurm.conf
slurmctld -D -i -f "$T/slurm.conf" >"$T/log/slurmctld.out" 2>&1 &
slurmd -D -N localhost -f "$T/slurm.conf" >"$T/log/slurmd.out" 2>&1 &
for _ in $(seq 1 300); do
  state=$(sinfo -h -N -o %t 2>/dev/null | head -1)
  [[ $state == idle ]] && exit 0
  sleep 0.1
done
reason="the node did not become idle in 30 s (state '${state:-none}'): $(tail -2 "$T/log/slurmd.log" 2>/dev/null) $(tail -2 "$T/log/slurmctld.log" 2>/dev/null)"
stop
cannot "$reason"

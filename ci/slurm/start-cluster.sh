#!/usr/bin/env bash
# Starts a single-node Slurm cluster on this machine for the Slurm test (tests/slurm.rs): munge
# for authentication, slurmctld and slurmd with a minimal configuration, this host as the one
# node with two CPUs (two array tasks at once). Needs root and Debian's slurm-wlm and munge.
# Idempotent: does nothing when the cluster already answers.
set -euo pipefail

if sinfo --noheader >/dev/null 2>&1 && [ -n "$(sinfo --noheader --states=idle,mix,alloc -o %n 2>/dev/null)" ]; then
    exit 0
fi
for tool in munged slurmctld slurmd sbatch; do
    command -v "$tool" >/dev/null || { echo "start-cluster.sh: $tool is missing (apt-get install slurm-wlm munge)" >&2; exit 1; }
done
[ "$(id -u)" -eq 0 ] || { echo "start-cluster.sh: needs root to start slurmctld and slurmd" >&2; exit 1; }

host=$(hostname -s)
cpus=$(nproc)
[ "$cpus" -ge 2 ] && cpus=2
state=/var/spool/slurm-prt-gpu
mkdir -p /etc/slurm "$state/ctld" "$state/d" /var/log/slurm /run/munge /var/lib/munge /var/log/munge

# munge: one key, made once.
if [ ! -s /etc/munge/munge.key ]; then
    dd if=/dev/urandom bs=1 count=1024 of=/etc/munge/munge.key status=none
fi
chown -R munge:munge /etc/munge /run/munge /var/lib/munge /var/log/munge 2>/dev/null || true
chmod 0400 /etc/munge/munge.key
pgrep -x munged >/dev/null || runuser -u munge -- /usr/sbin/munged

cat > /etc/slurm/slurm.conf <<CONF
# Written by ci/slurm/start-cluster.sh: one node, this host, for the tests.
ClusterName=prt-gpu-ci
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation=$state/ctld
SlurmdSpoolDir=$state/d
SlurmctldPidFile=/run/slurmctld.pid
SlurmdPidFile=/run/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
# No cgroups in containers: track processes by parent, bind nothing.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
NodeName=$host CPUs=$cpus State=UNKNOWN
PartitionName=ci Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
cat > /etc/slurm/cgroup.conf <<CONF
CgroupPlugin=autodetect
CgroupMountpoint=/sys/fs/cgroup
IgnoreSystemd=yes
CONF

pgrep -x slurmctld >/dev/null || slurmctld
pgrep -x slurmd >/dev/null || slurmd
for _ in $(seq 60); do
    if [ -n "$(sinfo --noheader --states=idle,mix,alloc -o %n 2>/dev/null)" ]; then
        exit 0
    fi
    sleep 1
done
echo "start-cluster.sh: the node did not come up; see /var/log/slurm/slurmctld.log and slurmd.log" >&2
sinfo >&2 || true
exit 1

#!/usr/bin/env bash
# snakemake --cluster-status for Slurm (samples/snakemake/slurm/config.yaml): prints
# "success", "failed" or "running" for the job id that `sbatch --parsable` printed
# ("12345" or "12345;cluster").  The state comes from sacct (accounting); where
# accounting is off, from scontrol while Slurm still knows the job.
set -uo pipefail
id="${1%%;*}"
state="$(sacct -j "$id" -X --noheader --parsable2 --format=State 2> /dev/null | head -n 1)"
if [ -z "$state" ]; then
  state="$(scontrol show job "$id" 2> /dev/null | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p' | head -n 1)"
fi
state="${state%% *}"  # "CANCELLED by 1234" -> "CANCELLED"
case "$state" in
  COMPLETED) echo success ;;
  "" | PENDING | CONFIGURING | RUNNING | COMPLETING | REQUEUED | REQUEUE_HOLD | REQUEUE_FED | RESIZING | SUSPENDED | STAGE_OUT | SIGNALING)
    echo running ;;  # "": not in accounting yet
  *) echo failed ;;  # FAILED, TIMEOUT, OUT_OF_MEMORY, CANCELLED, NODE_FAIL, PREEMPTED, BOOT_FAIL, DEADLINE
esac

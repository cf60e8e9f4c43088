#!/usr/bin/env bash
# End-to-end test of `hilcam replay` under a real Slurm scheduler (issue #25):
#  1. renders a short trajectory locally, in one `hilcam replay` process;
#  2. starts a private single-node cluster (cluster.sh up: munged, slurmctld, slurmd);
#  3. submits the same replay as a 4-task array (replay-array.sbatch), scancels one task
#     once it has written a frame and before its last, waits for the other tasks;
#  4. resubmits the cancelled task alone (sbatch --array=K), which resumes;
#  5. checks that hilcam refuses a resubmitted task whose shard count it cannot know
#     (SLURM_ARRAY_TASK_MIN ≠ 0, no HILCAM_SHARD_COUNT);
#  6. merges (merge.sh) and compares with the local run: every frame file and the
#     manifest byte for byte, and frames.jsonl byte for byte once the one field that holds
#     a wall clock (emit_unix_ns) is removed from both;
#  7. stops the cluster and checks that no munged, slurmctld, slurmd or slurmstepd is left.
# The cluster is stopped on any exit (trap). Needs root. HILCAM_BIN: the binary to test
# (default: target/debug/hilcam, built here: the dev profile is optimised, and
# `cargo test` has built it already in scripts/test.sh).
set -euo pipefail
cd "$(dirname "$0")/../.."
here=scripts/slurm
t0=$SECONDS
say() { printf 'test-cluster [%3ds]: %s\n' $((SECONDS - t0)) "$*"; }
fail() {
  say "FAIL: $*" >&2
  exit 1
}

if [ -z "${HILCAM_BIN:-}" ]; then
  nice cargo build --quiet --bin hilcam
  HILCAM_BIN=$PWD/target/debug/hilcam
fi
export HILCAM_BIN
"$here/../setup-slurm.sh"

# 25 frames (rows 0, 50, …, 1200) of the fly-around, ~0.3 s of CPU each, so that the
# cancelled task's 6 frames leave scancel (whose SIGTERM arrives a few hundred ms later)
# four frames to land before the last one; at a pinned integration time (the camera has
# auto-exposure, which cannot shard).
tasks=4
frames=25
replay_args=(--trajectory scenes/trajectories/flyaround.csv --scene scenes/satellite.toml
  --every 50 --width 512 --spp 32 --depth 3 --format png --integration-s 0.0002)
kill_task=1
per_task=$(((frames - kill_task + tasks - 1) / tasks))   # frames of task K: positions K, K+N, …

work=$(mktemp -d /tmp/hilcam-slurm-test.XXXXXX)
state=$work/cluster
# munged's socket directory (inside $state) must be reachable by all.
chmod 755 "$work"
daemons_left() {   # prints any munged, slurmctld, slurmd or slurmstepd process
  local n
  for n in munged slurmctld slurmd slurmstepd; do pgrep -a -x "$n" || true; done
}
finish() {
  local rc=$?
  env -u SLURM_CONF "$here/cluster.sh" down "$state" || rc=1
  if pgrep -a -f "$state" >&2 || [ -n "$(daemons_left | tee -a /dev/stderr)" ]; then
    say "FAIL: Slurm or MUNGE processes are still running (above)" >&2
    rc=1
  fi
  if [ "$rc" = 0 ]; then rm -rf "$work"; else say "kept $work for inspection" >&2; fi
  exit "$rc"
}
trap finish EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
if [ -n "$(daemons_left | tee -a /dev/stderr)" ]; then
  fail "Slurm or MUNGE daemons are already running (above); this test starts its own"
fi

say "local reference: hilcam replay ${replay_args[*]}"
"$HILCAM_BIN" replay "${replay_args[@]}" --out "$work/local" --threads 2 >"$work/local.log" 2>&1 ||
  { cat "$work/local.log" >&2; fail "the local replay failed"; }
[ "$(wc -l <"$work/local/frames.jsonl")" = "$frames" ] || fail "the local run has not $frames frames"

"$here/cluster.sh" up "$state"
export SLURM_CONF=$state/slurm.conf
out=$work/slurm
mkdir -p "$work/logs"
submit() {   # submit ARRAY: the replay array script for those task ids; prints the job id
  HILCAM_SHARD_COUNT=$tasks sbatch --parsable --array="$1" --chdir="$PWD" \
    --output="$work/logs/%A_%a.out" "$here/replay-array.sbatch" "${replay_args[@]}" --out "$out"
}
wait_job() {   # wait_job JOB: until no task of JOB is pending, running or completing
  local i
  for ((i = 0; i < 1200; i++)); do
    [ -z "$(squeue -h -j "$1" -o %i 2>/dev/null)" ] && return 0
    sleep 0.1
  done
  squeue >&2
  fail "job $1 still queued or running after 120 s"
}
task_state() {   # task_state JOB K: Slurm's JobState and ExitCode of task K
  scontrol -o show job "$1" | grep -E "(^| )ArrayTaskId=$2 " | grep -oE 'JobState=[A-Z_]+ .*ExitCode=[0-9:]+' |
    sed -E 's/JobState=([A-Z_]+) .*ExitCode=([0-9:]+)/\1 \2/'
}
lines() { if [ -f "$1" ]; then wc -l <"$1"; else echo 0; fi; }

job=$(submit "0-$((tasks - 1))")
say "submitted job array $job (tasks 0-$((tasks - 1)), shard K/$tasks each)"
kill_log=$out/frames.shard-$kill_task-of-$tasks.jsonl
for ((i = 0; i < 1200; i++)); do
  [ "$(lines "$kill_log")" -ge 1 ] && break
  sleep 0.05
done
[ "$(lines "$kill_log")" -ge 1 ] || fail "task $kill_task wrote no frame within 60 s"
scancel "${job}_$kill_task"
say "scancel ${job}_$kill_task after $(lines "$kill_log") of its $per_task frames"
wait_job "$job"
for ((k = 0; k < tasks; k++)); do
  s=$(task_state "$job" "$k")
  say "task $k: $s, $(lines "$out/frames.shard-$k-of-$tasks.jsonl") frames"
  if [ "$k" = "$kill_task" ]; then
    [[ "$s" == CANCELLED* ]] || fail "task $k should be CANCELLED, is $s"
  else
    [ "$s" = "COMPLETED 0:0" ] || { cat "$work/logs/${job}_$k.out" >&2; fail "task $k: $s"; }
  fi
done
done_before=$(lines "$kill_log")
[ "$done_before" -lt "$per_task" ] ||
  fail "task $kill_task finished all $per_task frames before scancel stopped it: nothing to resume (frames too fast?)"
grep -q "stopped by SIGTERM" "$work/logs/${job}_$kill_task.out" ||
  { cat "$work/logs/${job}_$kill_task.out" >&2; fail "task $kill_task did not report SIGTERM"; }

# A resubmitted task without HILCAM_SHARD_COUNT: Slurm says MIN = K, COUNT = 1; hilcam
# must refuse instead of rendering "shard 0 of 1" (the whole trajectory).
bad=$(env -u HILCAM_SHARD_COUNT sbatch --parsable --array="$kill_task" --chdir="$PWD" \
  --output="$work/logs/%A_%a.out" --wrap "'$HILCAM_BIN' replay ${replay_args[*]} --out '$work/refused'")
wait_job "$bad"
s=$(task_state "$bad" "$kill_task")
[[ "$s" == FAILED* ]] || fail "hilcam replay without --shard in a resubmitted task: $s, not FAILED"
grep -q "environment variable SLURM_ARRAY_TASK_MIN: is $kill_task" "$work/logs/${bad}_$kill_task.out" ||
  { cat "$work/logs/${bad}_$kill_task.out" >&2; fail "no SLURM_ARRAY_TASK_MIN refusal"; }
[ ! -e "$work/refused/frames.jsonl" ] || fail "the refused task wrote frames"
say "without HILCAM_SHARD_COUNT, --array=$kill_task is refused: $(grep -o 'SLURM_ARRAY_TASK_MIN: is [0-9]*' "$work/logs/${bad}_$kill_task.out")"

again=$(submit "$kill_task")
wait_job "$again"
s=$(task_state "$again" "$kill_task")
[ "$s" = "COMPLETED 0:0" ] || { cat "$work/logs/${again}_$kill_task.out" >&2; fail "resubmitted task $kill_task: $s"; }
[ "$(lines "$kill_log")" = "$per_task" ] || fail "task $kill_task has $(lines "$kill_log") of $per_task frames after resuming"
grep -q "$done_before already done" "$work/logs/${again}_$kill_task.out" ||
  { cat "$work/logs/${again}_$kill_task.out" >&2; fail "the resubmitted task did not resume from $done_before frames"; }
say "resubmitted task $kill_task (job $again): resumed from $done_before frames, now $per_task"

HILCAM_BIN=$HILCAM_BIN "$here/merge.sh" "$out" "$frames" | sed 's/^/  /'
# The local run and the merged shards: the same frame files, the same bytes.
files() { (cd "$1" && find . -maxdepth 1 -type f ! -name '*.jsonl' | sort); }
files "$work/local" >"$work/local.files"
files "$out" >"$work/slurm.files"
cmp "$work/local.files" "$work/slurm.files" || fail "the directories hold different files"
while read -r f; do
  cmp "$work/local/$f" "$out/$f" || fail "$f differs between the local run and the cluster"
done <"$work/local.files"
# emit_unix_ns is the wall clock at which the frame was encoded; all else must match.
strip() { sed -E 's/"emit_unix_ns":[0-9]+,?//' "$1"; }
cmp <(strip "$work/local/frames.jsonl") <(strip "$out/frames.jsonl") || fail "frames.jsonl differs (besides emit_unix_ns)"
say "$(wc -l <"$work/local.files") files byte-identical to the local run; frames.jsonl identical but for emit_unix_ns"

trap - EXIT
env -u SLURM_CONF "$here/cluster.sh" down "$state"
if [ -n "$(daemons_left | tee -a /dev/stderr)" ]; then
  fail "Slurm or MUNGE processes are still running after down (above)"
fi
rm -rf "$work"
say "PASS (no munged, slurmctld, slurmd or slurmstepd left)"

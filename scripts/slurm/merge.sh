#!/usr/bin/env bash
# Merge a sharded replay directory once every array task is done:
#   scripts/slurm/merge.sh OUT [FRAMES]
# runs `hilcam replay --merge OUT` (the shards' logs → OUT/frames.jsonl) and fails when a
# frame is missing: a gap that hilcam reports, or (given FRAMES, the expected frame
# count) fewer or more lines than FRAMES, which also catches missing frames at the end.
# HILCAM_BIN: the binary (default: `hilcam` on PATH).
set -euo pipefail
if [ $# -lt 1 ] || [ $# -gt 2 ]; then
  echo "usage: $0 OUT [FRAMES]" >&2
  exit 2
fi
out=$1
report=$("${HILCAM_BIN:-hilcam}" replay --merge "$out")
echo "$report"
if grep -q '^missing frames' <<<"$report"; then
  echo "merge.sh: $out: frames are missing (above); rerun those array tasks" >&2
  exit 1
fi
if [ $# -eq 2 ]; then
  n=$(wc -l <"$out/frames.jsonl")
  if [ "$n" -ne "$2" ]; then
    echo "merge.sh: $out/frames.jsonl has $n frames, expected $2; rerun the array tasks that did not finish" >&2
    exit 1
  fi
fi

#!/usr/bin/env bash
# Validates scripts/k8s/replay-indexed-job.yaml (or the manifests given) offline:
#  1. against the Kubernetes OpenAPI schema of the versions below, strictly (an unknown
#     field is an error), with kubernetes-validate from PyPI (its schemas ship inside the
#     package; installed into the project's venv by scripts/setup-python.sh);
#  2. HILCAM_SHARD_COUNT = .spec.completions for each Indexed Job (shard_count.py).
# Then it proves that both checks bite: three broken copies of the first manifest (a
# string where the schema wants an integer, a misspelt field, a shard count that is not
# the completions) must each be refused, or this script fails.
set -euo pipefail
cd "$(dirname "$0")/../.."
here=scripts/k8s
versions=(1.33.0 1.37.0)   # 1.33: backoffLimitPerIndex is GA; 1.37: the newest bundled
py=$(scripts/setup-python.sh)
kv=$(dirname "$py")/kubernetes-validate
manifests=("$@")
[ ${#manifests[@]} -gt 0 ] || manifests=("$here/replay-indexed-job.yaml")

# Both checks on one file; quiet unless it fails.
valid() {
  local v log
  for v in "${versions[@]}"; do
    if ! log=$("$kv" --strict --quiet -k "$v" "$1" 2>&1); then
      echo "$log"
      return 1
    fi
  done
  "$py" "$here/shard_count.py" "$1" 2>&1
}

for m in "${manifests[@]}"; do
  if ! valid "$m"; then
    echo "validate.sh: $m is not valid (above)" >&2
    exit 1
  fi
  echo "validate.sh: $m: valid for Kubernetes ${versions[*]} (strict) and HILCAM_SHARD_COUNT = completions"
done

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for fault in wrong-type unknown-field count-mismatch; do
  "$py" "$here/shard_count.py" --break "$fault" "${manifests[0]}" "$tmp/$fault.yaml"
  if why=$(valid "$tmp/$fault.yaml"); then
    echo "validate.sh: a manifest with a $fault fault passed validation" >&2
    exit 1
  fi
  echo "validate.sh: refused as it should, $fault: $(grep -m1 -E 'ERROR|must be' <<<"$why" || echo "$why" | head -1)"
done

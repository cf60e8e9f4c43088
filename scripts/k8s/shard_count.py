"""What the Kubernetes schema cannot check in an Indexed Job manifest for `hilcam replay`.

    python shard_count.py MANIFEST.yaml          # exit 1, naming the Job, when it fails
    python shard_count.py --break KIND IN OUT    # write a deliberately broken copy

Every Indexed Job must give its `hilcam` container HILCAM_SHARD_COUNT equal to
.spec.completions (pod K renders shard K of HILCAM_SHARD_COUNT: a smaller count renders
frames twice and a larger one leaves frames nobody renders).
"""

import sys

import yaml


def indexed_jobs(docs):
    return [d for d in docs if d and d.get("kind") == "Job" and d["spec"].get("completionMode") == "Indexed"]


def check(path):
    with open(path) as f:
        docs = list(yaml.safe_load_all(f))
    jobs = indexed_jobs(docs)
    if not jobs:
        return [f"{path}: no Indexed Job"]
    errors = []
    for job in jobs:
        name = job["metadata"]["name"]
        completions = job["spec"].get("completions")
        for c in job["spec"]["template"]["spec"]["containers"]:
            env = {e["name"]: e.get("value") for e in c.get("env", [])}
            count = env.get("HILCAM_SHARD_COUNT")
            if count != str(completions):
                errors.append(
                    f"{path}: Job {name}, container {c['name']}: env HILCAM_SHARD_COUNT = {count!r}, "
                    f"but .spec.completions = {completions}; they must be equal"
                )
    return errors


def break_manifest(kind, src, dst):
    """A copy of src with one fault the validators must refuse."""
    with open(src) as f:
        docs = list(yaml.safe_load_all(f))
    job = indexed_jobs(docs)[0]
    container = job["spec"]["template"]["spec"]["containers"][0]
    if kind == "wrong-type":  # an integer field given a string
        job["spec"]["completions"] = "four"
    elif kind == "unknown-field":  # a misspelt field, which Kubernetes would drop silently
        container["volumeMount"] = container.pop("volumeMounts")
    elif kind == "count-mismatch":  # valid for Kubernetes, wrong for hilcam
        job["spec"]["completions"] += 1
    else:
        sys.exit(f"unknown fault {kind}")
    with open(dst, "w") as f:
        yaml.safe_dump_all(docs, f, sort_keys=False)


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--break":
        break_manifest(*sys.argv[2:])
    elif len(sys.argv) == 2:
        problems = check(sys.argv[1])
        for p in problems:
            print(p, file=sys.stderr)
        sys.exit(1 if problems else 0)
    else:
        sys.exit(__doc__)

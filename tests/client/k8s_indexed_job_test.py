#!/usr/bin/env python3
"""The Kubernetes Indexed Job of docker/k8s/campaign-indexed-job.yaml, run on this machine.

The manifest's own campaign spec (its ConfigMap) and its container's own command are run pod by pod, as
the Job would: JOB_COMPLETION_INDEX = 0 .. completions - 1 and the container's env, with its volume
mounts (/spec, /results) mapped to temporary directories and the image's scenes
(/usr/share/moreau/scenes, docker/Dockerfile) to the source tree's. Then `moreau campaign --collect`, as
the manifest's header says. The collected records must equal the same campaign run in one piece, sample
for sample, and so must the summary. The spec keeps every field but its sample count (64 here), so that
the test takes seconds. No cluster is involved: this checks the manifest's spec, wiring and command line.

  k8s_indexed_job_test.py MOREAU SOURCE_DIR
"""
import json
import os
import subprocess
import sys
import tempfile

import yaml

SAMPLES = 64


def fail(message):
    print("FAIL: " + message)
    sys.exit(1)


def records(directory):
    files = []
    if os.path.exists(os.path.join(directory, "samples.jsonl")):
        files.append(os.path.join(directory, "samples.jsonl"))
    parts = os.path.join(directory, "parts")
    if os.path.isdir(parts):
        files += [os.path.join(parts, f) for f in sorted(os.listdir(parts))]
    out = {}
    for name in files:
        with open(name) as f:
            for line in f:
                r = json.loads(line)
                if r["index"] in out:
                    fail("sample %d twice in %s" % (r["index"], directory))
                # What depends on the machine's clock, not on the sample.
                r.pop("wall_seconds", None)
                out[r["index"]] = r
    return out


def main():
    moreau, source = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    manifest = os.path.join(source, "docker", "k8s", "campaign-indexed-job.yaml")
    with open(manifest) as f:
        documents = [d for d in yaml.safe_load_all(f) if d]
    by_kind = {d["kind"]: d for d in documents}
    for kind in ("ConfigMap", "PersistentVolumeClaim", "Job"):
        if kind not in by_kind:
            fail("the manifest has no %s" % kind)
    config_map, claim, job = by_kind["ConfigMap"], by_kind["PersistentVolumeClaim"], by_kind["Job"]

    # The Job's wiring: indexed, as many pods at once as tasks, TASKS equal to completions, the spec
    # volume from the ConfigMap and the results volume from the claim.
    job_spec = job["spec"]
    if job_spec.get("completionMode") != "Indexed":
        fail("the Job is not Indexed")
    completions = int(job_spec["completions"])
    pod = job_spec["template"]["spec"]
    container = pod["containers"][0]
    env = {e["name"]: str(e["value"]) for e in container.get("env", [])}
    if env.get("TASKS") != str(completions):
        fail("TASKS = %r but completions = %d" % (env.get("TASKS"), completions))
    volumes = {v["name"]: v for v in pod["volumes"]}
    mounts = {m["name"]: m["mountPath"] for m in container["volumeMounts"]}
    spec_volume = volumes[next(n for n in mounts if "configMap" in volumes[n])]
    if spec_volume["configMap"]["name"] != config_map["metadata"]["name"]:
        fail("the spec volume names ConfigMap %r, the manifest defines %r" % (spec_volume["configMap"]["name"], config_map["metadata"]["name"]))
    results_name = next(n for n in mounts if "persistentVolumeClaim" in volumes[n])
    if volumes[results_name]["persistentVolumeClaim"]["claimName"] != claim["metadata"]["name"]:
        fail("the results volume names another claim than the manifest's")
    if container["command"] != ["sh", "-c"] or len(container["args"]) != 1:
        fail("expected command [sh, -c] and one script in args")
    script = container["args"][0]

    image_scenes = "/usr/share/moreau/scenes/"
    with open(os.path.join(source, "docker", "Dockerfile")) as f:
        if "COPY scenes/ " + image_scenes not in f.read():
            fail("docker/Dockerfile does not put the scenes at " + image_scenes)
    spec = json.loads(config_map["data"]["campaign.json"])
    if not spec["scene"].startswith(image_scenes):
        fail("the spec's scene is not one of the image's: " + spec["scene"])

    with tempfile.TemporaryDirectory(prefix="moreau-k8s-") as tmp:
        local_dirs = {name: os.path.join(tmp, name) for name in mounts}
        for d in local_dirs.values():
            os.makedirs(d)
        spec["scene"] = os.path.join(source, "scenes", spec["scene"][len(image_scenes):])
        spec["samples"] = SAMPLES
        config_file = next(iter(config_map["data"]))
        spec_dir = local_dirs[next(n for n in mounts if "configMap" in volumes[n])]
        with open(os.path.join(spec_dir, config_file), "w") as f:
            json.dump(spec, f)
        for name, path in mounts.items():
            script = script.replace(path.rstrip("/") + "/", local_dirs[name] + "/")
        bin_dir = os.path.join(tmp, "bin")
        os.makedirs(bin_dir)
        os.symlink(moreau, os.path.join(bin_dir, "moreau"))
        pod_env = dict(os.environ, PATH=bin_dir + os.pathsep + os.environ["PATH"], **env)
        for k in range(completions):
            done = subprocess.run(["sh", "-c", script], env=dict(pod_env, JOB_COMPLETION_INDEX=str(k)), capture_output=True, text=True)
            if done.returncode != 0:
                fail("pod %d exited %d: %s%s" % (k, done.returncode, done.stdout, done.stderr))
        out_dir = os.path.join(local_dirs[results_name], "robust")
        parts = sorted(os.listdir(os.path.join(out_dir, "parts")))
        if len(parts) != completions:
            fail("expected %d part files, got %s" % (completions, parts))
        done = subprocess.run([moreau, "campaign", "--collect", out_dir], capture_output=True, text=True)
        if done.returncode != 0 or not os.path.exists(os.path.join(out_dir, "summary.json")):
            fail("collect exited %d: %s%s" % (done.returncode, done.stdout, done.stderr))

        local = os.path.join(tmp, "local")
        done = subprocess.run([moreau, "campaign", os.path.join(spec_dir, config_file), "--out", local, "-j", "2", "--quiet"],
                              capture_output=True, text=True)
        if done.returncode != 0:
            fail("the local campaign exited %d: %s" % (done.returncode, done.stderr))
        a, b = records(out_dir), records(local)
        if sorted(a) != list(range(SAMPLES)):
            fail("the pods wrote samples %s" % sorted(a))
        for i in range(SAMPLES):
            if a[i] != b[i]:
                fail("sample %d differs from the local campaign's" % i)
        with open(os.path.join(out_dir, "summary.json")) as f, open(os.path.join(local, "summary.json")) as g:
            if json.load(f) != json.load(g):
                fail("the summaries differ")
        print("%d pods, %d samples and the summary equal to the local campaign's" % (completions, SAMPLES))
        print("PASS")


if __name__ == "__main__":
    main()

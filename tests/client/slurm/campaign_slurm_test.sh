#!/bin/bash
# A campaign through a real single-node Slurm cluster (cluster.sh), against the same campaign run on
# this machine: a 4-task job array and its dependent collect job give the same records, sample for
# sample, and the same summary; after a task is "killed" (its part cut in the middle of a record), the
# same --slurm command resubmits only that task, and the result is again the same.
#   campaign_slurm_test.sh MOREAU SOURCE_DIR
# Exit 0 passed, 1 failed, 77 skipped (the daemons cannot run here, and MOREAU_REQUIRE_SLURM is not 1;
# CI sets it, so that there a cluster that cannot start is a failure, never a skip).
set -uo pipefail
moreau=$1
src=$2
T=$(mktemp -d /tmp/moreau-slurm-XXXXXX)
chmod 755 "$T"
cleanup() {
  bash "$src/tests/client/slurm/cluster.sh" stop "$T/cluster"
  rm -rf "$T"
}
trap cleanup EXIT
fail() {
  echo "FAIL: $*"
  # What Slurm knows of every job (it keeps finished ones for MinJobAge, 300 s): state, exit code, reason.
  [[ -n ${SLURM_CONF:-} ]] && { echo "--- scontrol show jobs"; scontrol -o show jobs 2>&1 | tr ' ' '\n' | grep -E '^(JobId|ArrayTaskId|JobState|Reason|Restarts|ExitCode|Dependency)=' | paste -sd ' ' | sed 's/ JobId=/\nJobId=/g'; }
  for f in "$T"/cluster/log/*.log "$T"/slurm/slurm/*.out; do [[ -f $f ]] && { echo "--- $f"; tail -8 "$f"; }; done
  exit 1
}

bash "$src/tests/client/slurm/cluster.sh" start "$T/cluster" 2> "$T/start.err"
rc=$?
if [[ $rc == 3 ]]; then
  reason=$(cat "$T/start.err")
  [[ ${MOREAU_REQUIRE_SLURM:-} == 1 ]] && fail "MOREAU_REQUIRE_SLURM=1 but $reason"
  echo "SKIP: $reason"
  exit 77
fi
[[ $rc == 0 ]] || fail "cluster.sh start exited $rc: $(cat "$T/start.err")"
export SLURM_CONF=$T/cluster/slurm.conf
echo "cluster up: $(sinfo -h -N -o '%N %t %c CPUs')"

# The forced relay with uncertain force and initial speed: 64 Latin hypercube samples.
cat > "$T/spec.json" <<SPEC
{
  "name": "relay-slurm",
  "scene": "$src/scenes/forced-relay.json",
  "inputs": [
    {"path": "/parameters/f", "distribution": {"type": "uniform", "low": 0.0, "high": 1.0}},
    {"path": "/parameters/v0", "distribution": {"type": "log-uniform", "low": 0.1, "high": 2.0}}
  ],
  "sampler": "latin-hypercube",
  "samples": 64,
  "seed": 11
}
SPEC

# Until no job is pending, running or completing; squeue failing (slurmctld busy) is not an empty queue.
wait_for_queue() {
  local queue
  for _ in $(seq 1 1200); do
    if queue=$(squeue -h 2>&1); then [[ -z $queue ]] && return 0; fi
    sleep 0.1
  done
  squeue
  fail "the jobs did not finish in 120 s"
}

out=$("$moreau" campaign "$T/spec.json" --out "$T/slurm" --slurm --tasks 4 --time 10) || fail "moreau campaign --slurm: $out"
echo "$out"
[[ $out == *"4 of 4 tasks (64 samples missing of 64)"* ]] || fail "expected 4 tasks submitted: $out"
wait_for_queue
[[ -f $T/slurm/summary.json ]] || fail "the collect job wrote no summary.json"
parts=$(ls "$T/slurm/parts")
[[ $parts == $'0-16.jsonl\n16-32.jsonl\n32-48.jsonl\n48-64.jsonl' ]] || fail "expected four complete part files, got: $parts"
grep -q "samples" "$T"/slurm/slurm/collect-*.out || fail "the collect job printed no summary"

"$moreau" campaign "$T/spec.json" --out "$T/local" -j 2 --quiet > /dev/null 2>&1 || fail "the local campaign failed"

compare() {
  /usr/bin/python3 - "$T/slurm" "$T/local" <<'PY' || fail "the Slurm and local campaigns differ"
import json, os, sys
def records(d):
    files = [os.path.join(d, "samples.jsonl")] if os.path.exists(os.path.join(d, "samples.jsonl")) else []
    parts = os.path.join(d, "parts")
    if os.path.isdir(parts):
        files += [os.path.join(parts, f) for f in sorted(os.listdir(parts))]
    out = {}
    for f in files:
        for line in open(f):
            r = json.loads(line)
            assert r["index"] not in out, "sample %d twice" % r["index"]
            # What depends on the machine's clock, not on the sample.
            r.pop("wall_seconds"); r["report"].pop("wall_seconds", None); r["report"].pop("phase_seconds", None)
            out[r["index"]] = r
    return out
a, b = records(sys.argv[1]), records(sys.argv[2])
assert sorted(a) == list(range(64)), sorted(a)
for i in range(64):
    assert a[i] == b[i], "sample %d differs" % i
sa = json.load(open(os.path.join(sys.argv[1], "summary.json")))
sb = json.load(open(os.path.join(sys.argv[2], "summary.json")))
assert sa == sb, "the summaries differ"
print("64 samples and the summary equal, %d succeeded" % sa["successes"])
PY
}
compare

# A task killed in the middle of a record: its part is left as .partial with a cut last line, and no
# summary. The same command resubmits that task alone; it keeps the complete records and redoes the rest.
part=$T/slurm/parts/16-32.jsonl
head -n 5 "$part" > "$part.partial"
head -n 6 "$part" | tail -n 1 | head -c 40 >> "$part.partial"
rm "$part" "$T/slurm/summary.json"
"$moreau" campaign --collect "$T/slurm" > "$T/collect.out" 2>&1 && fail "collect accepted a cut part"
grep -q "16-32.jsonl.partial' line 6 is cut short" "$T/collect.out" || fail "collect did not name the cut part: $(cat "$T/collect.out")"
out=$("$moreau" campaign "$T/spec.json" --out "$T/slurm" --slurm --tasks 4 --time 10) || fail "resubmission: $out"
echo "$out"
[[ $out == *"1 of 4 tasks (11 samples missing of 64)"* ]] || fail "expected only task 1 resubmitted, for its 11 missing samples: $out"
wait_for_queue
[[ -f $T/slurm/summary.json ]] || fail "the collect job wrote no summary.json after the resubmission"
[[ ! -e $part.partial && -f $part ]] || fail "the resubmitted task did not complete its part"
compare
echo "PASS"

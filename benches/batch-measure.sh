#!/bin/bash
# Batch measurements on 100 small synthetic models (release binary): throughput with --jobs 1
# and 2, the rerun that skips them all, and a SIGTERM followed by a resumed run. The figures of
# a run are in benches/results/*-batch.md.
set -u
B=${B:-target/release/scanatlas}
W=${W:-/tmp/btm}
rm -rf "$W"; mkdir -p "$W"
for i in $(seq 0 99); do $B -q synth "$W/in/m$(printf %03d $i)" --faces 2000 --sheet-size 256 --seed $((i+1)); done
echo "load before: $(cat /proc/loadavg)"
for k in 1 2; do
  /usr/bin/time -f "jobs=$k wall %e s, largest process RSS %M KiB" $B -q --threads 2 batch "$W/in" -o "$W/out$k" --jobs $k
  python3 - "$W/out$k" <<'PY'
import json, sys
e = [json.loads(l) for l in open(sys.argv[1] + "/batch.jsonl")]
ok = [x for x in e if x["status"] == "ok"]
print(f"  ok {len(ok)}, model wall mean {sum(x['wall_s'] for x in ok)/len(ok):.2f} s, "
      f"model peak RSS max {max(x['peak_rss_bytes'] for x in ok)/2**20:.1f} MiB, "
      f"mean {sum(x['peak_rss_bytes'] for x in ok)/len(ok)/2**20:.1f} MiB, threads {ok[0]['threads']}")
PY
done
echo "load after: $(cat /proc/loadavg)"
# Outputs do not depend on --jobs or the threads per model.
diff -r -q -x run.log -x batch.jsonl -x report.json -x .batch-record.json "$W/out1" "$W/out2" && echo "out1 == out2 (models and sheets byte-identical)"
for r in 1 2 3; do /usr/bin/time -f "rerun skipping 100: wall %e s" $B -q batch "$W/in" -o "$W/out1"; done
# Kill and resume.
$B -q --threads 2 batch "$W/in" -o "$W/out3" --jobs 1 & pid=$!
sleep 8; kill -TERM $pid; wait $pid; echo "batch after SIGTERM: exit $?"
python3 - "$W/out3" <<'PY'
import json, sys, collections
e = [json.loads(l) for l in open(sys.argv[1] + "/batch.jsonl")]
print("  after kill:", dict(collections.Counter(x["status"] for x in e)))
PY
/usr/bin/time -f "resume: wall %e s" $B -q --threads 2 batch "$W/in" -o "$W/out3" --jobs 1; echo "resume exit $?"
python3 - "$W/out3" <<'PY'
import json, sys, collections
e = [json.loads(l) for l in open(sys.argv[1] + "/batch.jsonl")]
by = collections.defaultdict(list)
for x in e: by[x["name"]].append(x["status"])
print("  status sequences:", dict(collections.Counter(tuple(v) for v in by.values())))
print("  models with exactly one ok:", sum(1 for v in by.values() if v.count("ok") == 1), "of", len(by))
PY
diff -r -q -x run.log -x batch.jsonl -x report.json -x .batch-record.json -x '.*.tmp' "$W/out1" "$W/out3" && echo "out3 (killed and resumed) == out1"
find "$W/out3" -name '*.tmp' | head

#!/usr/bin/env bash
# Load test of moreau-server on 127.0.0.1: for each scenario, starts a fresh server (small queue, so that
# 429s happen), records its resident memory, drives it with bench/load_test (hundreds of concurrent
# connections submitting small jobs for a fixed time, every answer checked), waits for the queue to
# drain, checks that every accepted job finished "done" with its report stored, and records the memory
# again after a few seconds. Prints one table at the end. Results: docs/reliability.md ("Load").
#
#   scripts/load-test.sh [BUILD_DIR]          (default build/; builds moreau-server and load_test there)
#
# Environment: DURATION (s, default 20), QUEUE (16), WORKERS (2), SETTLE (s before "after" memory, 5),
# TIMEOUT (client connect/read timeout, s, 10), SCENARIOS (default below: CONNECTIONS:MAX_CONNECTIONS:MODE,
# MODE keep-alive or close = a new connection per request), DATA_ROOT (where data directories go, TMPDIR),
# SERVER_BINARY (another moreau-server to measure).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
duration=${DURATION:-20}
queue=${QUEUE:-16}
workers=${WORKERS:-2}
settle=${SETTLE:-5}
timeout=${TIMEOUT:-10}
# connections:--max-connections (also per client: the load comes from one address):mode. With a new
# connection per request, a client that has read its answer reconnects while the server's thread for the
# old connection may not yet have closed it (a slot is free once that thread ends: microseconds on a
# quiet machine, longer at a load average of 100 and more), so that scenario gets the largest --max-connections (900).
scenarios=${SCENARIOS:-"256:272:keep-alive 512:528:keep-alive 512:900:close"}
data_root=${DATA_ROOT:-${TMPDIR:-/tmp}}

cmake --build "$build" --target moreau-server load_test >/dev/null
server=${SERVER_BINARY:-$build/server/moreau-server}
client=$build/bench/load_test
[ -x "$server" ] && [ -x "$client" ] || { echo "missing $server or $client" >&2; exit 2; }
ulimit -n 65536 2>/dev/null || ulimit -n "$(ulimit -Hn)"

log_dir=$(mktemp -d "$data_root/moreau-load-XXXXXX")
server_pid=
cleanup() {
  if [ -n "$server_pid" ] && kill -0 "$server_pid" 2>/dev/null; then
    kill -KILL "$server_pid" 2>/dev/null || true
    wait "$server_pid" 2>/dev/null || true
  fi
}
trap cleanup EXIT

kib() { awk -v k="$2" '$1 == k":" { print $2 }' "/proc/$1/status"; }
mib() { awk -v k="$1" 'BEGIN { printf "%.1f", k / 1024 }'; }
field() { tr ' ' '\n' <"$1" | awk -F= -v k="$2" '$1 == k { print $2 }'; }

loadavg_before=$(cut -d' ' -f1-3 /proc/loadavg)
rows=()
status=0
n=0
for scenario in $scenarios; do
  IFS=: read -r conns max_conns mode <<<"$scenario"
  n=$((n + 1))
  data=$(mktemp -d "$data_root/moreau-load-data-XXXXXX")
  out=$log_dir/$n
  echo "== scenario $n: $conns connections ($mode), --max-connections $max_conns, --queue $queue, --workers $workers, ${duration} s"
  "$server" --host 127.0.0.1 --port 0 --data "$data" --workers "$workers" --queue "$queue" \
    --max-connections "$max_conns" --max-connections-per-client "$max_conns" >"$out.server.out" 2>"$out.server.err" &
  server_pid=$!
  port=
  for _ in $(seq 1 500); do
    port=$(sed -n 's|.*listening on http://127\.0\.0\.1:\([0-9]*\).*|\1|p' "$out.server.out")
    [ -n "$port" ] && break
    kill -0 "$server_pid" 2>/dev/null || { cat "$out.server.err"; exit 1; }
    sleep 0.02
  done
  [ -n "$port" ] || { echo "moreau-server did not start" >&2; exit 1; }
  sleep 1
  rss_base=$(kib "$server_pid" VmRSS)
  threads_base=$(kib "$server_pid" Threads)

  # Threads of the server, sampled while the load runs (peak).
  (
    peak=0
    while kill -0 "$server_pid" 2>/dev/null; do
      t=$(awk '$1 == "Threads:" { print $2 }' "/proc/$server_pid/status" 2>/dev/null || echo 0)
      [ "${t:-0}" -gt "$peak" ] && peak=$t && echo "$peak" >"$out.threads"
      sleep 0.2
    done
  ) &
  sampler=$!

  client_args=(--port "$port" --connections "$conns" --duration "$duration" --timeout "$timeout")
  [ "$mode" = close ] && client_args+=(--no-keep-alive)
  start=$(date +%s.%N)
  if ! "$client" "${client_args[@]}" >"$out.client" 2>&1; then status=1; fi
  cat "$out.client" | grep -v '^RESULT'
  sleep "$settle"
  rss_after=$(kib "$server_pid" VmRSS)
  rss_peak=$(kib "$server_pid" VmHWM)
  health=$(curl -s -o /dev/null -w '%{http_code}' "http://127.0.0.1:$port/healthz" || echo none)
  jobs_on_disk=$(find "$data/jobs" -mindepth 1 -maxdepth 1 -type d | wc -l)
  disk=$(du -sm "$data" | cut -f1)
  kill -TERM "$server_pid"
  server_exit=0
  wait "$server_pid" || server_exit=$?
  server_pid=
  kill "$sampler" 2>/dev/null || true
  wait "$sampler" 2>/dev/null || true
  threads_peak=$(cat "$out.threads" 2>/dev/null || echo "?")
  errors_logged=$(grep -c . "$out.server.err" || true)
  echo "   server: healthz $health after the run, exit $server_exit on SIGTERM, $errors_logged lines on stderr;" \
    "RSS $(mib "$rss_base") / $(mib "$rss_peak") / $(mib "$rss_after") MiB (baseline / peak / after);" \
    "threads $threads_base -> $threads_peak; $jobs_on_disk job directories, $disk MiB on disk"
  r=$(grep '^RESULT' "$out.client")
  echo "$r" >"$out.result"
  [ "$(field "$out.result" ok)" = 1 ] && [ "$health" = 200 ] && [ "$server_exit" = 0 ] || status=1
  rows+=("$(printf '| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s / %s / %s | %s / %s / %s |' \
    "$conns" "$mode" "$max_conns" "$(field "$out.result" seconds)" "$(field "$out.result" rps)" \
    "$(field "$out.result" accepted)" "$(field "$out.result" refused)" \
    "$(( $(field "$out.result" other) + $(field "$out.result" conn_errors) ))" \
    "$(field "$out.result" verified_done)" \
    "$(field "$out.result" p50_ms)" "$(field "$out.result" p99_ms)" "$(field "$out.result" max_ms)" \
    "$(mib "$rss_base")" "$(mib "$rss_peak")" "$(mib "$rss_after")")")
  rm -rf "$data"
done

echo
echo "moreau-server load test: --queue $queue, --workers $workers, ${duration} s per scenario, $(nproc) cores," \
  "load average $loadavg_before before, $(cut -d' ' -f1-3 /proc/loadavg) after"
echo
echo "| connections | mode | --max-connections | s | requests/s | 202 accepted | 429 refused | errors | accepted jobs done and stored | latency p50 / p99 / max (ms) | RSS MiB baseline / peak / after |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
printf '%s\n' "${rows[@]}"
echo
echo "(errors: answers other than 202 and 429, plus requests without an answer: connect or read failures,"
echo " read timeout ${timeout} s; logs in $log_dir)"
exit $status

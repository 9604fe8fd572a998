#!/bin/sh
# LCM over udpm:// between two processes, inside a private network namespace.
#
#   tests/server/lcm_udpm_netns.sh MOREAU_SERVER_BINARY MOREAU_BINARY DIR
#
# Creates a user and network namespace (unshare -rn) that has nothing but its own loopback interface,
# turns multicast on for it and routes 224.0.0.0/4 there, then runs moreau-server (publishing on
# udpm://239.255.76.67:7667?ttl=0) and `moreau watch --log` as separate processes, submits a streamed,
# realtime job with `moreau submit` and waits for it. No packet can reach the machine's real network.
# Leaves DIR/watch.log (what the watcher received) and DIR/report.json (the finished job) for
# tests/server/lcm_stream_test.cc to decode, then interrupts a second watch with SIGINT (DIR/interrupt.out and
# DIR/interrupt.rc, its output and exit status). Run from the source tree (it submits scenes/manipulator.json).
set -eu
[ $# -eq 3 ] || { echo "usage: $0 MOREAU_SERVER_BINARY MOREAU_BINARY DIR" >&2; exit 2; }

exec unshare -rn sh -eu -c '
server=$1 client=$2 dir=$3
ip link set lo up
ip link set lo multicast on
ip route add 224.0.0.0/4 dev lo
url="udpm://239.255.76.67:7667?ttl=0"
export MOREAU_SERVER=http://127.0.0.1:18080

"$server" --port 18080 --data "$dir/data" --lcm-url "$url" --workers 1 >"$dir/server.out" 2>&1 &
server_pid=$!
watch_pid=
cleanup() {
  [ -z "$watch_pid" ] || kill "$watch_pid" 2>/dev/null || true
  kill "$server_pid" 2>/dev/null || true
  wait 2>/dev/null || true
}
trap cleanup EXIT
# Waits (at most 10 s) until a watch has written "listening on" to its output file $1: it has subscribed.
wait_listening() {
  i=0
  until grep -q "listening on" "$1" 2>/dev/null; do
    i=$((i + 1))
    if [ $i -ge 200 ]; then echo "moreau watch did not start:"; cat "$1"; exit 1; fi
    sleep 0.05
  done
}

i=0
until "$client" scenes >/dev/null 2>&1; do
  i=$((i + 1))
  if [ $i -ge 200 ]; then echo "moreau-server did not start:"; cat "$dir/server.out"; exit 1; fi
  sleep 0.05
done

"$client" watch --lcm-url "$url" --log "$dir/watch.log" --until-finished --timeout 30 --plain >"$dir/watch.out" 2>&1 &
watch_pid=$!
wait_listening "$dir/watch.out"

"$client" submit scenes/manipulator.json --set integrator.t_end=1.5 --stream --realtime --wait --json >"$dir/report.json"
wait "$watch_pid"
watch_pid=
echo "watch:"; cat "$dir/watch.out"

# Ctrl-C ends a watch normally: exit status 0 and a one-line summary (DIR/interrupt.out, .rc).
"$client" watch --lcm-url "$url" --plain >"$dir/interrupt.out" 2>&1 &
watch_pid=$!
wait_listening "$dir/interrupt.out"
kill -INT "$watch_pid"
rc=0
wait "$watch_pid" || rc=$?
watch_pid=
echo "$rc" >"$dir/interrupt.rc"
echo "interrupted watch (exit $rc):"; cat "$dir/interrupt.out"
' sh "$1" "$2" "$3"

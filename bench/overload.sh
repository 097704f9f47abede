#!/usr/bin/env bash
# Goodput under overload: wrk drives POST /v1/decompose (bench/overload.lua) at several
# connection counts against a spawned server (2 workers, queue 32); prints goodput
# (successful decompositions/s), the 503 count, p50/p99 latency and the server's peak RSS.
# Usage: bench/overload.sh target/release/truecut [SECONDS] [CONNECTIONS...]
set -euo pipefail
cd "$(dirname "$0")/.."
bin="$1"; shift
secs="${1:-15}"; shift || true
if [ "$#" -gt 0 ]; then conns=("$@"); else conns=(32 48 64); fi
work="$(mktemp -d)"
port="$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
"$bin" serve --addr "127.0.0.1:${port}" --data-dir "${work}/data" --workers 2 --queue 32 \
  > "${work}/server.log" 2>&1 &
server=$!
trap 'kill ${server} 2>/dev/null; wait ${server} 2>/dev/null; rm -rf "${work}"' EXIT
for _ in $(seq 1 100); do curl -sf "http://127.0.0.1:${port}/healthz" >/dev/null && break; sleep 0.1; done
wrk -t2 -c8 -d3s -s bench/overload.lua "http://127.0.0.1:${port}/v1/decompose" >/dev/null  # warm-up
for c in "${conns[@]}"; do
  line="$(wrk -t2 -c"$c" -d"${secs}s" --timeout 10s -s bench/overload.lua "http://127.0.0.1:${port}/v1/decompose" | grep RESULT)"
  echo "connections ${c}: ${line#RESULT }"
done
echo "server VmHWM: $(grep VmHWM /proc/${server}/status | awk '{printf "%.1f MiB", $2/1024}')"

#!/usr/bin/env bash
# A bounded schemathesis run against a spawned server (fresh data dir, demo data, a free
# port): every documented operation is fuzzed with positive and negative examples, and the
# run fails on any 5xx, any answer outside the documented statuses, content types or
# response schemas. Usage: .ci/schemathesis.sh [BINARY] (default target/debug/truecut).
# SCHEMATHESIS_EXAMPLES (default 30) and SCHEMATHESIS_MAX_TIME (s, default 150) bound it;
# SCHEMATHESIS_SEED (default 13) picks another draw when looking for more failures.
set -euo pipefail
cd "$(dirname "$0")/.."
bin="${1:-target/debug/truecut}"
examples="${SCHEMATHESIS_EXAMPLES:-30}"
max_time="${SCHEMATHESIS_MAX_TIME:-150}"
work="$(mktemp -d)"
port="$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
"$bin" serve --addr "127.0.0.1:${port}" --data-dir "${work}/data" --demo --workers 2 \
  > "${work}/server.log" 2>&1 &
server=$!
cleanup() {
  kill "${server}" 2>/dev/null || true
  wait "${server}" 2>/dev/null || true
  if grep -q "internal error\|framework error\|panicked" "${work}/server.log"; then
    echo "== server log lines about 5xx:"; grep -m 20 "internal error\|framework error\|panicked" "${work}/server.log"
  fi
  rm -rf "${work}"
}
trap cleanup EXIT
for _ in $(seq 1 150); do
  curl -sf "http://127.0.0.1:${port}/healthz" >/dev/null && break
  sleep 0.2
done
curl -sf "http://127.0.0.1:${port}/healthz" >/dev/null || { cat "${work}/server.log"; exit 1; }
# schemathesis runs on one thread: on two, its own coverage phase crashes inside CPython's ast
# module now and then ("Runtime Error", "AST constructor recursion depth mismatch", seen
# 2026-11-26 and 2026-11-27), and the run had to be repeated. One thread draws as many cases
# in the same time (23,958 in 240 s against 23,314 on two, 2026-11-27): the server answers
# faster than the tool generates. Should the tool still crash inside itself (a Runtime Error
# and no failed check), the run is repeated once; a run with a check failure (a 5xx, a
# schema violation) is never repeated.
st_run() {
  schemathesis run openapi.yaml \
    --url "http://127.0.0.1:${port}" \
    --checks not_a_server_error,status_code_conformance,content_type_conformance,response_schema_conformance,response_headers_conformance \
    --max-examples "${examples}" \
    --max-time "${max_time}" \
    --seed "${SCHEMATHESIS_SEED:-13}" \
    --workers "$1" \
    --request-timeout 60 \
    --suppress-health-check all \
    --warnings off
}
set +e
st_run 1 2>&1 | tee "${work}/st.log"
status=${PIPESTATUS[0]}
set -e
if [ "$status" -ne 0 ] && grep -q "Runtime Error" "${work}/st.log" \
  && grep -Eq '^ *[0-9]+ generated, [0-9]+ passed *$' "${work}/st.log"; then
  echo "schemathesis crashed inside itself (Runtime Error, no failed check): running it again"
  st_run 1
  status=$?
fi
exit "$status"

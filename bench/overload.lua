-- wrk script: POST /v1/decompose with a 2,025-sample signal (about 40 kB of JSON) and count
-- the answers by status. Goodput = decompositions answered 200 per second.
-- Run by bench/overload.sh; by hand: wrk -t2 -c32 -d15s -s bench/overload.lua http://127.0.0.1:PORT/v1/decompose
local n = 2025
local values = {}
for i = 1, n do
  local x = (i - 1) / n
  values[i] = string.format("%.6f", 0.01 * math.sin(2 * math.pi * 7 * x) + 0.004 * math.sin(2 * math.pi * 90 * x) + 0.002 * x)
end
wrk.method = "POST"
wrk.body = '{"signal":[' .. table.concat(values, ",") .. ']}'
wrk.headers["Content-Type"] = "application/json"

local threads = {}
function setup(thread)
  table.insert(threads, thread)
end

function init(args)
  ok, busy, other = 0, 0, 0
end

function response(status, headers, body)
  if status == 200 then
    ok = ok + 1
  elseif status == 503 then
    busy = busy + 1
  else
    other = other + 1
  end
end

function done(summary, latency, requests)
  local o, b, x = 0, 0, 0
  for _, t in ipairs(threads) do
    o = o + t:get("ok")
    b = b + t:get("busy")
    x = x + t:get("other")
  end
  local secs = summary.duration / 1e6
  io.write(string.format(
    "RESULT goodput %.1f/s ok %d busy(503) %d other %d socket_errors %d p50 %.1f ms p99 %.1f ms\n",
    o / secs, o, b, x,
    summary.errors.connect + summary.errors.read + summary.errors.write + summary.errors.timeout,
    latency:percentile(50) / 1000, latency:percentile(99) / 1000))
end

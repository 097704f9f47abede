#!/usr/bin/env python3
"""Peak resident memory of the service under N concurrent maximum-size probe uploads.

Starts the given truecut binary on a free port with a fresh data dir, creates a machine and
a flat surface whose grid has exactly as many points as each upload has rows (1024 per grid
row, as many grid rows as fit in SIZE MiB), then sends N (default 8) point uploads of SIZE
MiB (default 120) at once, each with its Content-Length, from N threads.

Modes (--mode):
  refused  (default) every row is read and parsed, and the last one is not a number, so the
           upload is refused 400 naming that line: the parse's worst case, nothing stored.
  stored   every row is valid: the points are paired with the nominal grid and stored (201).
Formats (--format): csv (default; `x,y,z` rows) or json (`{"points": [[x, y, z], ...]}`).

The surface's PUT (itself a large body) happens first, then the server is restarted on the
same data dir and its peak reset (/proc/PID/clear_refs, 5), so that VmHWM covers the uploads
only. Prints each answer's status
and time, the parsed arrays' size of one upload (points: 24 bytes a row; stored: plus the
deviations, 8 bytes a row), and the server's peak RSS above its level before the uploads.

Usage: python3 bench/concurrent_uploads.py target/release/truecut [N] [SIZE_MIB]
           [--mode refused|stored] [--format csv|json] [-- extra serve flags]
(e.g. `-- --max-inflight-body-mb 2048` to let all N bodies in at once).
"""
import http.client
import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time

args = sys.argv[1:]
extra = []
if "--" in args:
    extra = args[args.index("--") + 1:]
    args = args[: args.index("--")]
mode, fmt = "refused", "csv"
positional = []
i = 0
while i < len(args):
    if args[i] == "--mode":
        mode = args[i + 1]
        i += 2
    elif args[i] == "--format":
        fmt = args[i + 1]
        i += 2
    else:
        positional.append(args[i])
        i += 1
binary = positional[0]
n = int(positional[1]) if len(positional) > 1 else 8
size_mib = float(positional[2]) if len(positional) > 2 else 120.0
assert mode in ("refused", "stored") and fmt in ("csv", "json"), (mode, fmt)
NU = 1024


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def status_kb(pid, key):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    return 0


def request(port, method, path, body=b"", ctype="application/json", timeout=900):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    c.request(method, path, body=body, headers={"Content-Type": ctype, "Content-Length": str(len(body))})
    r = c.getresponse()
    data = r.read()
    c.close()
    return r.status, data


def grid_row(j):
    """One grid row of measured points: the nominal (i, j, 0) plus 0.0123456 mm along z."""
    if fmt == "csv":
        return "".join(f"{i}.000500,{j}.000300,0.0123456\n" for i in range(NU)).encode()
    return ",".join(f"[{i}.000500,{j}.000300,0.0123456]" for i in range(NU)).encode()


def build_body():
    target = int(size_mib * 1024 * 1024)
    head, tail = (b"x,y,z\n", b"") if fmt == "csv" else (b'{"points":[', b"]}")
    parts, size, j = [head], len(head) + len(tail), 0
    while True:
        row = grid_row(j)
        if size + len(row) + 1 > target:
            break
        if fmt == "json" and j > 0:
            parts.append(b",")
            size += 1
        parts.append(row)
        size += len(row)
        j += 1
    if mode == "refused":  # the last value is not a number: refused after the whole parse
        last = parts[-1]
        parts[-1] = last[: last.rfind(b"0.0123456")] + (b"x.0123456" if fmt == "csv" else b'"x"') + (b"\n" if fmt == "csv" else b"]")
    parts.append(tail)
    return b"".join(parts), j


port = free_port()
data_dir = tempfile.mkdtemp(prefix="truecut-rss-")


def start_server():
    proc = subprocess.Popen(
        [binary, "serve", "--addr", f"127.0.0.1:{port}", "--data-dir", data_dir, *extra],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    for _ in range(400):
        try:
            if request(port, "GET", "/healthz")[0] == 200:
                break
        except OSError:
            time.sleep(0.05)
    return proc


server = start_server()
try:
    body, nv = build_body()
    rows = NU * nv
    machine = {"kinematics": "xyz", "axes": {"X": {"kv": 30}, "Y": {"kv": 30}, "Z": {"kv": 30}}}
    assert request(port, "PUT", "/v1/machines/m", json.dumps(machine).encode())[0] in (200, 201)
    points = ",".join(f"[{i},{j},0]" for j in range(nv) for i in range(NU))
    normals = ",".join(["[0,0,1]"] * rows)
    surface = f'{{"nominal":{{"grid":{{"nu":{NU},"nv":{nv},"points":[{points}],"normals":[{normals}]}}}}}}'.encode()
    del points, normals
    status, data = request(port, "PUT", "/v1/machines/m/surfaces/s", surface)
    assert status in (200, 201), (status, data[:300])
    del surface
    # A fresh process on the same data dir, so that the heap the surface's PUT left behind
    # neither counts nor serves the uploads.
    server.terminate()
    server.wait()
    server = start_server()
    assert request(port, "GET", "/v1/machines/m/surfaces")[0] == 200
    time.sleep(0.5)
    with open(f"/proc/{server.pid}/clear_refs", "w") as f:
        f.write("5")  # reset VmHWM to the current RSS
    base_rss = status_kb(server.pid, "VmRSS")
    parsed = rows * (24 if mode == "refused" else 32)
    print(f"{n} {fmt} uploads of {len(body) / 2**20:.1f} MiB ({rows:,} points each, mode {mode}), "
          f"server pid {server.pid}; parsed arrays of one upload {parsed / 2**20:.1f} MiB")
    results = [None] * n
    start = time.time()

    def upload(k):
        t0 = time.time()
        try:
            ctype = "text/csv" if fmt == "csv" else "application/json"
            status, data = request(port, "POST", "/v1/machines/m/surfaces/s/measurements", body, ctype)
            detail = json.loads(data).get("detail", "")[:90] if data else ""
        except OSError as e:
            status, detail = "error", str(e)
        results[k] = (status, time.time() - t0, detail)

    threads = [threading.Thread(target=upload, args=(k,)) for k in range(n)]
    for t in threads:
        t.start()
    peak_rss = 0
    while any(t.is_alive() for t in threads):
        peak_rss = max(peak_rss, status_kb(server.pid, "VmRSS"))
        time.sleep(0.02)
    for t in threads:
        t.join()
    total = time.time() - start
    for k, (status, took, detail) in enumerate(results):
        print(f"  upload {k}: {status} after {took:.2f} s  {detail}")
    hwm = status_kb(server.pid, "VmHWM")
    above = (hwm - base_rss) * 1024
    print(f"RSS before the uploads {base_rss / 1024:.1f} MiB; during them VmRSS peaked at "
          f"{peak_rss / 1024:.1f} MiB (sampled every 20 ms); VmHWM {hwm / 1024:.1f} MiB "
          f"= {hwm * 1024 / 1e6:.0f} MB; peak above the level before: {above / 2**20:.1f} MiB "
          f"= {above / parsed:.2f} x one upload's parsed arrays; all answered in {total:.1f} s")
finally:
    server.terminate()
    server.wait()
    subprocess.run(["rm", "-rf", data_dir])

#!/usr/bin/env python3
"""Peak resident memory of the service under N concurrent maximum-size probe uploads.

Starts the given truecut binary on a free port with a fresh data dir, creates a machine and
a 2 x 2 surface, then sends N (default 8) CSV point uploads of SIZE MiB (default 120) at
once, each with its Content-Length, from N threads. Every body is read and parsed whole
before the point count is compared with the surface's, so this is the server's worst case
for memory per upload. Prints each answer's status and time, and the server's VmHWM (peak
RSS) from /proc/PID/status, before and after.

Usage: python3 bench/concurrent_uploads.py target/release/truecut [N] [SIZE_MIB] [-- extra serve flags]
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
binary = args[0]
n = int(args[1]) if len(args) > 1 else 8
size_mib = float(args[2]) if len(args) > 2 else 120.0


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


def request(port, method, path, body=b"", ctype="application/json", timeout=600):
    c = http.client.HTTPConnection("127.0.0.1", port, timeout=timeout)
    c.request(method, path, body=body, headers={"Content-Type": ctype, "Content-Length": str(len(body))})
    r = c.getresponse()
    data = r.read()
    c.close()
    return r.status, data


port = free_port()
data_dir = tempfile.mkdtemp(prefix="truecut-rss-")
server = subprocess.Popen(
    [binary, "serve", "--addr", f"127.0.0.1:{port}", "--data-dir", data_dir, *extra],
    stdout=subprocess.DEVNULL,
    stderr=subprocess.DEVNULL,
)
try:
    for _ in range(200):
        try:
            if request(port, "GET", "/healthz")[0] == 200:
                break
        except OSError:
            time.sleep(0.05)
    machine = {"kinematics": "xyz", "axes": {"X": {"kv": 30}, "Y": {"kv": 30}, "Z": {"kv": 30}}}
    assert request(port, "PUT", "/v1/machines/m", json.dumps(machine).encode())[0] in (200, 201)
    surface = {"nominal": {"grid": {"nu": 2, "nv": 2,
               "points": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]],
               "normals": [[0, 0, 1]] * 4}}}
    assert request(port, "PUT", "/v1/machines/m/surfaces/s", json.dumps(surface).encode())[0] in (200, 201)

    line = b"123.456789,234.567891,0.0123456\n"
    rows = int(size_mib * 1024 * 1024) // len(line)
    body = b"x,y,z\n" + line * rows
    print(f"{n} uploads of {len(body) / 2**20:.1f} MiB ({rows:,} points each), server pid {server.pid}")
    base_hwm = status_kb(server.pid, "VmHWM")
    results = [None] * n
    start = time.time()

    def upload(i):
        t0 = time.time()
        try:
            status, data = request(port, "POST", "/v1/machines/m/surfaces/s/measurements", body, "text/csv")
            detail = json.loads(data).get("detail", "")[:90] if data else ""
        except OSError as e:
            status, detail = "error", str(e)
        results[i] = (status, time.time() - t0, detail)

    threads = [threading.Thread(target=upload, args=(i,)) for i in range(n)]
    for t in threads:
        t.start()
    peak_rss = 0
    while any(t.is_alive() for t in threads):
        peak_rss = max(peak_rss, status_kb(server.pid, "VmRSS"))
        time.sleep(0.02)
    for t in threads:
        t.join()
    total = time.time() - start
    for i, (status, took, detail) in enumerate(results):
        print(f"  upload {i}: {status} after {took:.2f} s  {detail}")
    hwm = status_kb(server.pid, "VmHWM")
    print(f"baseline VmHWM {base_hwm / 1024:.1f} MiB; during the uploads VmRSS peaked at "
          f"{peak_rss / 1024:.1f} MiB (sampled every 20 ms); VmHWM {hwm / 1024:.1f} MiB "
          f"= {hwm * 1024 / 1e6:.0f} MB; all answered in {total:.1f} s")
finally:
    server.terminate()
    server.wait()
    subprocess.run(["rm", "-rf", data_dir])

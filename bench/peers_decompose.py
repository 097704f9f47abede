#!/usr/bin/env python3
"""Times the Python peer pipeline (vmdpy/lean VMD, PyEMD, PyWavelets) against truecut's
coarse-to-fine decomposition on the same signals, in the same run, and prints the ratios.

Usage (from the crate root):  python3 bench/peers_decompose.py [--sizes 2025 20000 250000]
                              python3 bench/peers_decompose.py --peer lean --peer-path FILE
                                  [--rounds 5] [--sizes 2025 20000] [--signals numpy bench]
                                  [--ours-bin target/release/deps/decompose-HASH]

`--peer vmdpy` (default): the peer pipeline below (vmdpy, two-iterate transcription above
20,000 samples), timed after our bench.
`--peer lean`: the memory-lean NumPy peer of the seed-002 reference study (`peer_pipeline.py`,
its `method_c2f` with `vmd_impl="lean"`: vmdpy's arithmetic keeping two iterates). It is not
part of this crate: give its path with `--peer-path FILE` or `TRUECUT_PEER_PIPELINE=FILE`
(in the project's shared folder: reference/decomposition/peer_pipeline.py). The peer and
our bench (in process and over HTTP) then run interleaved, `--rounds` times, and each side's
best time is compared (the machine is shared; the minimum is the least disturbed run).

The signals are the paper's eq. 23 continued with step 0.01 (t = 1 + 0.01 k) plus
N(0, 0.005 mm) noise; they are written to a temporary folder that
`cargo bench --bench decompose -- --signals DIR` reads, so both sides see identical input.
`--signals` names the noise: `numpy` (default; numpy default_rng(0)) or `bench` (the Rust
bench's own `paper_signal`, rand StdRng seed 0, written by `cargo bench --bench decompose --
--write-signals DIR`), or both (`--signals numpy bench`: one table each, same run). They are
not equally hard for the peer: on numpy's noise its VMD needs 232 iterations at 20,000
samples, on the bench's it converges sooner (issue 41 measured the ratio there).
Peer pipeline as REPORT.md (seed 002 reference): VMD K=7, alpha 2000, tau 0, DC 0, init 1,
tol 1e-7, at most 500 iterations -> |r| > 0.3 -> X1; PyEMD EMD() of X1 -> screening against
the measured error -> X2; weak parts -> db4 soft universal threshold (max level) -> X3.
vmdpy keeps every iterate (2.2 GB at n = 20000, 28 GB at 250000), so above 20000 samples the
peer VMD is a two-iterate NumPy transcription of vmdpy's arithmetic (as the REPORT's
`vmd_lean`). BLAS threads are pinned to 1 as the REPORT advises for stable timings.
"""
import importlib.util
import json, os, subprocess, sys, tempfile, time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")


def ensure(pkgs):
    missing = [pip for mod, pip in pkgs if importlib.util.find_spec(mod) is None]
    if missing:
        subprocess.check_call([sys.executable, "-m", "pip", "install", "-q", *missing])


ensure([("numpy", "numpy"), ("pywt", "PyWavelets"), ("PyEMD", "EMD-signal"), ("vmdpy", "vmdpy"), ("scipy", "scipy")])

import numpy as np  # noqa: E402
import pywt  # noqa: E402
from PyEMD import EMD  # noqa: E402
from vmdpy import VMD  # noqa: E402


def vmd_lean(f, alpha=2000.0, tau=0.0, K=7, tol=1e-7, niter=500):
    """vmdpy's arithmetic (mirror, one-sided Wiener updates, omega centroid), two iterates."""
    N = len(f)
    h = (N + 1) // 2
    fm = np.concatenate([f[:h][::-1], f, f[h:][::-1]])
    T = len(fm)
    freqs = np.arange(1, T + 1) / T - 0.5 - 1 / T
    f_hat = np.fft.fftshift(np.fft.fft(fm))
    f_hat_plus = f_hat.copy()
    f_hat_plus[: T // 2] = 0
    u = np.zeros((K, T), dtype=complex)
    omega = np.array([0.5 / K * i for i in range(K)])
    lam = np.zeros(T, dtype=complex)
    n, udiff = 0, tol + np.spacing(1)
    pos = slice(T // 2, T)
    while udiff > tol and n < niter - 1:
        u_old = u.copy()
        total = u.sum(axis=0)
        for k in range(K):
            total -= u[k]
            u[k] = (f_hat_plus - total - lam / 2) / (1.0 + alpha * (freqs - omega[k]) ** 2)
            p = np.abs(u[k, pos]) ** 2
            omega[k] = np.dot(freqs[pos], p) / np.sum(p)
            total += u[k]
        lam = lam + tau * (total - f_hat_plus)
        n += 1
        d = u - u_old
        udiff = np.spacing(1) + np.sum(np.real(d * np.conj(d))) / T
    full = np.zeros((K, T), dtype=complex)
    full[:, pos] = u[:, pos]
    idx = np.arange(1, T // 2 + 1)[::-1]
    full[:, idx] = np.conj(u[:, pos])
    full[:, 0] = np.conj(full[:, -1])
    modes = np.real(np.fft.ifft(np.fft.ifftshift(full, axes=1), axis=1))
    return modes[:, h : h + N]


def peer_c2f(x):
    n = len(x)
    if n <= 20000:
        xe = x if n % 2 == 0 else np.append(x, x[-1])
        modes, _, _ = VMD(xe, 2000.0, 0.0, 7, 0, 1, 1e-7)
        modes = modes[:, :n]
    else:
        modes = vmd_lean(x)
    r = np.array([abs(np.corrcoef(m, x)[0, 1]) for m in modes])
    x1 = modes[r > 0.3].sum(axis=0)
    imfs = EMD()(x1)
    r2 = np.array([abs(np.corrcoef(c, x)[0, 1]) for c in imfs])
    x2 = imfs[r2 > 0.3].sum(axis=0)
    w = modes[r <= 0.3].sum(axis=0) + imfs[r2 <= 0.3].sum(axis=0)
    c = pywt.wavedec(w, "db4", mode="symmetric")
    sigma = np.median(np.abs(c[-1])) / 0.6745
    lam = sigma * np.sqrt(2 * np.log(n))
    c = [c[0]] + [pywt.threshold(d, lam, "soft") for d in c[1:]]
    x3 = pywt.waverec(c, "db4", mode="symmetric")[:n]
    return x2 + x3


def arg(name, default=None):
    if name in sys.argv:
        return sys.argv[sys.argv.index(name) + 1]
    return default


def int_list(name):
    if name not in sys.argv:
        return None
    out = []
    for a in sys.argv[sys.argv.index(name) + 1 :]:
        if not a.isdigit():
            break
        out.append(int(a))
    return out


def write_signals(tmp, sizes, kind="numpy", crate=None):
    """Writes `tmp/signal_N.json` for each size with the noise of `kind` (`numpy` or `bench`,
    see the module doc) and returns the signals and the true systematic errors."""
    if kind == "bench":
        binary = arg("--ours-bin")
        cmd = [binary] if binary else ["cargo", "bench", "--bench", "decompose", "--"]
        subprocess.run(
            [*cmd, "--write-signals", tmp, "--sizes", *map(str, sizes)],
            cwd=crate, check=True, capture_output=True, text=True,
        )
    signals, truths = {}, {}
    for n in sizes:
        t = 1 + 0.01 * np.arange(n)
        s = 0.04 * (np.sin(1.6 * np.pi * t) + np.cos(0.05 * np.pi * t) + 4 * np.exp(-3 * t))
        path = os.path.join(tmp, f"signal_{n}.json")
        if kind == "bench":
            with open(path) as fh:
                x = np.array(json.load(fh))
        else:
            x = s + np.random.default_rng(0).normal(0, 0.005, n)
            with open(path, "w") as fh:
                json.dump(x.tolist(), fh)
        signals[n] = x
        truths[n] = s
    return signals, truths


def signal_kinds():
    kinds = []
    if "--signals" in sys.argv:
        for a in sys.argv[sys.argv.index("--signals") + 1 :]:
            if a not in ("numpy", "bench"):
                break
            kinds.append(a)
        if not kinds:
            sys.exit("--signals takes numpy, bench or both")
    return kinds or ["numpy"]


def run_ours(crate, tmp, sizes):
    # `--ours-bin PATH`: a bench binary built elsewhere (e.g. from an older commit, for a
    # before/after table against the same peer run) instead of `cargo bench`.
    binary = arg("--ours-bin")
    cmd = [binary] if binary else ["cargo", "bench", "--bench", "decompose", "--"]
    out = subprocess.run(
        [*cmd, "--signals", tmp, "--sizes", *map(str, sizes)],
        cwd=crate, check=True, capture_output=True, text=True,
    ).stdout
    return {d["n"]: d for d in (json.loads(line) for line in out.splitlines() if line.startswith("{"))}


def load_lean_peer():
    path = arg("--peer-path", os.environ.get("TRUECUT_PEER_PIPELINE"))
    if not path or not os.path.isfile(path):
        sys.exit(
            "--peer lean needs the peer's file, which is not part of this crate: pass "
            "--peer-path FILE or set TRUECUT_PEER_PIPELINE=FILE (the seed-002 reference "
            "peer_pipeline.py, in the shared folder at reference/decomposition/peer_pipeline.py)"
            + (f"; not found: {path}" if path else "")
        )
    spec = importlib.util.spec_from_file_location("peer_pipeline", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    params = dict(mod.DEFAULTS, vmd_impl="lean")
    return path, lambda x: mod.method_c2f(x, params)


def main_lean():
    path, peer = load_lean_peer()
    sizes = int_list("--sizes") or [2025, 20000]
    rounds = int(arg("--rounds", "5"))
    crate = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    print(f"peer: {path} (method_c2f, vmd_impl lean); {rounds} interleaved rounds, best of each side")
    for kind in signal_kinds():
        print()
        print(f"## signals: {kind} noise")
        lean_round_trip(peer, crate, sizes, rounds, kind)


def lean_round_trip(peer, crate, sizes, rounds, kind):
    print(f"load average at start: {os.getloadavg()}")
    with tempfile.TemporaryDirectory() as tmp:
        signals, truths = write_signals(tmp, sizes, kind, crate)
        best_peer = {n: float("inf") for n in sizes}
        info = {}
        ours = {}
        for r in range(rounds):
            o = run_ours(crate, tmp, sizes)
            for n, d in o.items():
                if n not in ours:
                    ours[n] = dict(d)
                    continue
                for key in ("coarse_to_fine_s", "stages_1_4_s", "vmd_s", "http_s"):
                    ours[n][key] = min(ours[n][key], d[key])
                for key, v in d["profile_ms"].items():
                    ours[n]["profile_ms"][key] = min(ours[n]["profile_ms"][key], v)
            for n in sizes:
                t0 = time.perf_counter()
                est, inf = peer(signals[n])
                best_peer[n] = min(best_peer[n], time.perf_counter() - t0)
                e = np.abs(est - truths[n])
                info[n] = (inf["vmd_info"]["iterations"], np.corrcoef(est, truths[n])[0, 1], e.max(), e.mean())
            print(f"  round {r + 1}/{rounds} done, load average {os.getloadavg()[0]:.1f}", flush=True)
        print(f"load average at end: {os.getloadavg()}")
        print()
        print(f"| signals | n | lean peer C2F (s) | VMD iterations peer / ours | truecut in process (s) "
              "| ratio (goal >= 100x) | truecut HTTP (s) | ratio (goal >= 30x) |")
        print("|---|---|---|---|---|---|---|---|")
        for n in sizes:
            o, p = ours[n], best_peer[n]
            print(f"| {kind} | {n:,} | {p:.4f} | {info[n][0]} / {o['vmd_iterations']} | {o['coarse_to_fine_s']:.5f} "
                  f"| {p / o['coarse_to_fine_s']:.1f}x | {o['http_s']:.5f} | {p / o['http_s']:.1f}x |")
        print()
        print("Where our time goes (ms, each stage alone, best of the rounds):")
        for n in sizes:
            print(f"  {n:,}: " + ", ".join(f"{k} {v:.2f}" for k, v in ours[n]["profile_ms"].items()))
        print()
        print("Accuracy against the true systematic error (r / max abs / mean abs, mm):")
        print("| signals | n | lean peer C2F | truecut C2F default |")
        print("|---|---|---|---|")
        for n in sizes:
            a = ours[n]["default_r_max_mean"]
            _, r, mx, mn = info[n]
            print(f"| {kind} | {n:,} | {r:.6f} / {mx:.6f} / {mn:.6f} | {a[0]:.6f} / {a[1]:.6f} / {a[2]:.6f} |")


def main():
    if arg("--peer", "vmdpy") == "lean":
        return main_lean()
    sizes = int_list("--sizes") or [2025, 20000, 250000]
    here = os.path.dirname(os.path.abspath(__file__))
    crate = os.path.dirname(here)
    kind = signal_kinds()[0]
    with tempfile.TemporaryDirectory() as tmp:
        signals, truths = write_signals(tmp, sizes, kind, crate)
        ours = run_ours(crate, tmp, sizes)
        print("| n | peers C2F (s) | truecut C2F default (s) | ratio | truecut stages 1-4 (s) | ratio |")
        print("|---|---|---|---|---|---|")
        acc = []
        for n in sizes:
            reps = 3 if n <= 2025 else 1
            times = []
            for _ in range(reps):
                t0 = time.perf_counter()
                est = peer_c2f(signals[n])
                times.append(time.perf_counter() - t0)
            peer = sorted(times)[len(times) // 2]
            e = np.abs(est - truths[n])
            acc.append((n, np.corrcoef(est, truths[n])[0, 1], e.max(), e.mean()))
            o = ours[n]
            print(
                f"| {n:,} | {peer:.3f} | {o['coarse_to_fine_s']:.4f} | {peer / o['coarse_to_fine_s']:.1f}x "
                f"| {o['stages_1_4_s']:.4f} | {peer / o['stages_1_4_s']:.1f}x |",
                flush=True,
            )
        print()
        print("Accuracy against the true systematic error (r / max abs / mean abs, mm):")
        print("| n | peers C2F | truecut C2F default | truecut stages 1-4 |")
        print("|---|---|---|---|")
        for n, r, mx, mn in acc:
            a, b = ours[n]["default_r_max_mean"], ours[n]["stages_r_max_mean"]
            print(
                f"| {n:,} | {r:.6f} / {mx:.6f} / {mn:.6f} | {a[0]:.6f} / {a[1]:.6f} / {a[2]:.6f} "
                f"| {b[0]:.6f} / {b[1]:.6f} / {b[2]:.6f} |"
            )


if __name__ == "__main__":
    main()

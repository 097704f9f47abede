#!/usr/bin/env python3
"""Python baselines for benches/step_error.rs (run by the bench in the same run).

* The Python study's geometric method: vectorised numpy golden-section search (60 iterations + end
  check) of the extremal distance from the CC curve to the CL line, over all 19,800 segments of
  surface 1 (formulas from tests/data/step/README.md; curve points from the analytic surface).
* A forward pass of the same network shape (inputs-28-20-2, ReLU) in numpy and, if installed, in
  PyTorch on CPU with 1 thread (float64 and float32).
Prints one JSON line of segments/s (last line); every rate is the best of 5-15 runs (the bench
machine is shared). Needs numpy; torch is optional (never installed by CI).
"""
import argparse, json, math, time
import numpy as np

TAU = 2 * math.pi
S1 = dict(lx=120.0, ly=140.0, S=17.08647059768471, C=19.234687045924023,
          sc=[(1.0, TAU / 115, 0.4, TAU / 135, 0.3)], g=[(0.8, 45, 85, 21, 24), (-0.7, 90, 35, 19, 22)])


def jet(x, y):
    z = np.zeros_like(x); fx = np.zeros_like(x); fy = np.zeros_like(x); fxx = np.zeros_like(x)
    for a, kx, px, ky, py in S1["sc"]:
        sx, cx = np.sin(kx * x + px), np.cos(kx * x + px)
        sy, cy = np.sin(ky * y + py), np.cos(ky * y + py)
        z += a * sx * cy; fx += a * kx * cx * cy; fy -= a * ky * sx * sy; fxx -= a * kx * kx * sx * cy
    for a, x0, y0, sx, sy in S1["g"]:
        dx, dy = x - x0, y - y0
        g = a * np.exp(-(dx * dx / (2 * sx * sx) + dy * dy / (2 * sy * sy)))
        z += g; fx -= g * dx / sx ** 2; fy -= g * dy / sy ** 2; fxx += g * (dx * dx / sx ** 2 - 1) / sx ** 2
    S, C = S1["S"], S1["C"]
    return S * z + C, S * fx, S * fy, S * fxx


def segments(R=5.0):
    u = np.arange(100) / 99 * S1["lx"]; v = np.arange(200) / 199 * S1["ly"]
    X, Y = np.meshgrid(u, v)  # (200, 100)
    z, fx, fy, _ = jet(X, Y)
    n = np.stack([-fx, -fy, np.ones_like(z)], -1); n /= np.linalg.norm(n, axis=-1, keepdims=True)
    P = np.stack([X, Y, z], -1); CL = P + R * n
    x0 = X[:, :-1].ravel(); x1 = X[:, 1:].ravel(); y = Y[:, :-1].ravel()
    a = CL[:, :-1].reshape(-1, 3); b = CL[:, 1:].reshape(-1, 3)
    return x0, x1, y, a, b


def golden(x0, x1, y, a, b, R=5.0, iters=60):
    d = b - a; d /= np.linalg.norm(d, axis=1, keepdims=True)
    xm = 0.5 * (x0 + x1)
    convex = jet(xm, y)[3] < 0
    sign = np.where(convex, 1.0, -1.0)

    def f(t):
        x = x0 + (x1 - x0) * t
        q = np.stack([x, y, jet(x, y)[0]], -1) - a
        c = np.cross(q, d)
        return sign * np.linalg.norm(c, axis=1)

    lo = np.zeros_like(x0); hi = np.ones_like(x0); gr = (math.sqrt(5) - 1) / 2
    c1 = hi - gr * (hi - lo); c2 = lo + gr * (hi - lo); f1 = f(c1); f2 = f(c2)
    for _ in range(iters):
        m = f1 < f2
        hi = np.where(m, c2, hi); lo = np.where(m, lo, c1)
        c2n = np.where(m, c1, lo + gr * (hi - lo)); c1n = np.where(m, hi - gr * (hi - lo), c2)
        c1, c2 = c1n, c2n
        fn = f(np.where(m, c1, c2))
        f1, f2 = np.where(m, fn, f2), np.where(m, f1, fn)
    best = np.minimum(np.minimum(f1, f2), np.minimum(f(np.zeros_like(x0)), f(np.ones_like(x0))))
    L = sign * best
    return np.abs(R - L)


def best_of(k, fn):
    t = []
    for _ in range(k):
        s = time.perf_counter(); fn(); t.append(time.perf_counter() - s)
    return min(t)


def main():
    ap = argparse.ArgumentParser(); ap.add_argument("--inputs", type=int, default=67); ap.add_argument("--outputs", type=int, default=2)
    args = ap.parse_args()
    out = {}
    segs = segments()
    n = len(segs[0])
    e = golden(*segs)
    out["golden_numpy_max_um"] = float(e.max() * 1000)
    out["golden_numpy_seg_per_s"] = n / best_of(5, lambda: golden(*segs))
    rng = np.random.default_rng(0)
    sizes = [args.inputs, 28, 20, args.outputs]
    W = [rng.standard_normal((i, o)) * math.sqrt(2 / i) for i, o in zip(sizes[:-1], sizes[1:])]
    B = [np.zeros(o) for o in sizes[1:]]
    X = rng.standard_normal((10 * n, args.inputs))

    def fwd(x):
        for k, (w, b) in enumerate(zip(W, B)):
            x = x @ w + b
            if k < len(W) - 1:
                np.maximum(x, 0, out=x)
        return x

    out["forward_numpy_seg_per_s"] = X.shape[0] / best_of(15, lambda: fwd(X))
    try:
        import torch
        torch.set_num_threads(1)
        for dt, key in ((torch.float64, "forward_torch_seg_per_s"), (torch.float32, "forward_torch32_seg_per_s")):
            net = torch.nn.Sequential(torch.nn.Linear(sizes[0], 28), torch.nn.ReLU(), torch.nn.Linear(28, 20), torch.nn.ReLU(),
                                      torch.nn.Linear(20, sizes[-1])).to(dt).eval()
            xt = torch.from_numpy(X).to(dt)
            with torch.inference_mode():
                out[key] = X.shape[0] / best_of(15, lambda: net(xt))
        out["torch"] = torch.__version__
    except ImportError:
        out["torch"] = None
    out["numpy"] = np.__version__
    print(json.dumps(out))


if __name__ == "__main__":
    main()

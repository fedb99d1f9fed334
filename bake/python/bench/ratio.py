"""Python against Rust, measured in one run: a batch of 65,536 point queries and a 256² splat
through the `otbake` package (numpy in, numpy out) and through the runtime directly (the lab
example `python_ratio`, the same calls), interleaved round by round on the same baked archives.

    cargo build --release -p otbake-lab --example python_ratio
    python bake/python/bench/ratio.py [--rounds 5] [--repeats 5]

Times are thread-CPU seconds per call (load on the machine barely moves them); the ratio is the
median over rounds of Python's over Rust's. Bakes its manifest (four 250K-point shapes, sliced
maps) into target/bench-python on first use.
"""

import argparse
import json
import subprocess
import time
from pathlib import Path

import numpy as np

import otbake

REPO = Path(__file__).resolve().parents[3]
SHAPES = (REPO / ".." / "shared" / "data" / "shapes").resolve()
N, RES = 65536, 256


def manifest():
    out = REPO / "target" / "bench-python"
    out.mkdir(parents=True, exist_ok=True)
    path = out / "shapes-250k.toml"
    inputs = "".join(
        f'\n[[input]]\nname = "{s}"\npath = "{SHAPES}/{s}.png"\ndensity = "inverted"\n'
        for s in ("redcross", "tooth", "heart", "duck")
    )
    path.write_text(
        f'[output]\ndir = "{out}/shapes"\n[proxy]\nkind = "gaussian"\nsamples = 250000\nseed = 0\n'
        f'[solver]\nkind = "sliced"\n{inputs}'
    )
    otbake.bake(path)
    return path


def python_side(blend, repeats):
    i = np.arange(N, dtype=np.float64)
    pts = np.ascontiguousarray(np.stack([(i * 0.7548776662) % 1.0, (i * 0.5698402910) % 1.0], 1).astype(np.float32))
    w = np.full(blend.k, 1.0 / blend.k, np.float32)
    sigma = np.float32(0.5) / np.float32(RES)

    def cpu(f):
        t = time.thread_time()
        for _ in range(repeats):
            out = f()
        return (time.thread_time() - t) / repeats, out

    tp, (d, _, _) = cpu(lambda: blend.point(w, pts, sigma))
    ts, (sd, _) = cpu(lambda: blend.splat(w, (RES, RES), sigma))
    return tp, ts, float(d.astype(np.float64).sum()), float(sd.astype(np.float64).sum())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    path = manifest()
    blend = otbake.open_manifest(path, bake_first=False)
    exe = REPO / "target" / "release" / "examples" / "python_ratio"
    rows = []
    for r in range(args.rounds):
        rust = json.loads(subprocess.run([str(exe), str(path), str(N), str(RES), str(args.repeats)], check=True, capture_output=True, text=True).stdout)
        tp, ts, psum, ssum = python_side(blend, args.repeats)
        assert np.isclose(psum, rust["point_sum"], rtol=1e-12), (psum, rust["point_sum"])
        assert np.isclose(ssum, rust["splat_sum"], rtol=1e-12), (ssum, rust["splat_sum"])
        rows.append((tp / rust["point_cpu"], ts / rust["splat_cpu"], tp, rust["point_cpu"], ts, rust["splat_cpu"]))
        print(f"round {r}: point {tp*1e3:.2f} ms (Rust {rust['point_cpu']*1e3:.2f} ms), splat {ts*1e3:.2f} ms (Rust {rust['splat_cpu']*1e3:.2f} ms)")
    a = np.array(rows)
    print(f"65,536 point queries: Python/Rust = {np.median(a[:, 0]):.3f} (median of {args.rounds} rounds)")
    print(f"256² splat: Python/Rust = {np.median(a[:, 1]):.3f}")


if __name__ == "__main__":
    main()

"""Fuzzes the Python entry points of the `otbake` package with hostile arguments.

    python bake/python/fuzz/fuzz_entry_points.py [--first INDEX] [EXECUTIONS] [SEED]
    python bake/python/fuzz/fuzz_entry_points.py --replay INDEX SEED

Each execution opens archives of the fuzz corpus (tests/fuzz/corpus/archive/, sometimes with
mutated bytes, sometimes from a path, sometimes from objects that are no archive), makes a `Blend`
(or a `BrdfBlend` of 3D maps) from maps that may be missing, repeated, of another proxy or not maps
at all, and calls its queries with hostile arrays: wrong dtypes (float64, int, bool, complex,
object, big-endian), wrong shapes, strided and Fortran-ordered views, empty arrays, NaN and
infinite values, weights of the wrong count or per-row weights of the wrong rows, out-of-range
indices, hostile kernels and splat resolutions; `shade` gets hostile arrays too, and manifest
parsing (`archives`) mutated manifests of tests/fuzz/corpus/manifest/.

Allowed outcomes are a result or an `otbake.Error`, `TypeError`, `ValueError` or `OverflowError`.
Anything else is a finding — a caught Rust panic (`PanicException`), `MemoryError`, `SystemError`,
any other exception, or a crash of the process (the campaign runs in a child process under a
6 GiB address-space limit; the parent writes the input of the execution that killed it).
Findings go to tests/fuzz/findings/python-SEED-INDEX/ and the exit status is 1.

Every execution draws from its own generator, seeded by (SEED, INDEX), so `--replay` reruns one
alone with its exception's traceback, and `--first INDEX` runs executions INDEX .. INDEX +
EXECUTIONS: a campaign in parts (run side by side on several cores) that add up, execution for
execution, to one campaign.
"""

import os
import random
import resource
import shutil
import subprocess
import sys
import tempfile
import time
import traceback
import warnings

import numpy as np
import otbake

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
CORPUS = os.path.join(ROOT, "tests", "fuzz", "corpus")
FINDINGS = os.path.join(ROOT, "tests", "fuzz", "findings")
ALLOWED = (otbake.Error, TypeError, ValueError, OverflowError)
ADDRESS_SPACE = 6 << 30


def load_cases():
    """Archive cases: (proxy bytes, [map bytes]) per folder of the archive corpus."""
    base = os.path.join(CORPUS, "archive")
    cases = []
    for name in sorted(os.listdir(base)):
        d = os.path.join(base, name)
        files = sorted(f for f in os.listdir(d) if f.endswith(".otb") and f != "proxy.otb")
        with open(os.path.join(d, "proxy.otb"), "rb") as f:
            proxy = f.read()
        maps = []
        for m in files:
            with open(os.path.join(d, m), "rb") as f:
                maps.append(f.read())
        cases.append((name, proxy, maps))
    return cases


def load_manifests():
    base = os.path.join(CORPUS, "manifest")
    out = []
    for name in sorted(os.listdir(base)):
        with open(os.path.join(base, name), "rb") as f:
            out.append(f.read())
    return out


SPECIAL = [0.0, -0.0, 1.0, -1.0, float("nan"), float("inf"), float("-inf"), 3.4e38, 1e-45, 1e30]


def mutate_bytes(rnd, b):
    """Byte-level damage (no checksum repair: the Rust `archive` target does that; here the open
    path's own checks are the point)."""
    b = bytearray(b)
    for _ in range(rnd.randint(1, 3)):
        if not b:
            break
        op = rnd.randrange(6)
        i = rnd.randrange(len(b))
        if op == 0:
            b[i] ^= 1 << rnd.randrange(8)
        elif op == 1:
            b[i] = rnd.randrange(256)
        elif op == 2:
            del b[rnd.randrange(len(b) + 1):]
        elif op == 3:
            j = i & ~3
            b[j:j + 4] = np.float32(rnd.choice(SPECIAL)).tobytes()
        elif op == 4:
            j = i & ~3
            b[j:j + 4] = rnd.choice([0, 1, 0xFFFFFFFF, 0x80000000]).to_bytes(4, "little")
        else:
            b.extend(b[: rnd.randrange(64)])
    return bytes(b)


class Context:
    def __init__(self, cases, manifests, scratch):
        self.cases = cases
        self.manifests = manifests
        self.scratch = scratch


def call(f, *args, **kwargs):
    """Runs one entry point; allowed errors are results, anything else propagates (a finding)."""
    try:
        return f(*args, **kwargs)
    except ALLOWED:
        return None


def source(rnd, data, ctx, tag):
    """An archive source: bytes, bytearray, a path, or something that is no archive."""
    op = rnd.randrange(40)
    if op < 34:
        return data
    if op < 36:
        return bytearray(data)
    if op < 38:
        p = os.path.join(ctx.scratch, tag + ".otb")
        with open(p, "wb") as f:
            f.write(data)
        return p if rnd.randrange(2) else __import__("pathlib").Path(p)
    return rnd.choice([
        os.path.join(ctx.scratch, "missing.otb"), ctx.scratch, b"", None, 17, 1.5,
        memoryview(data), np.frombuffer(data, dtype=np.uint8), [1, 2, 3], "",
    ])


def array(rnd, nrng, shape, dtype):
    """Mostly a valid array of `shape` and `dtype`, else one of many wrong ones."""
    op = rnd.randrange(24)
    if op < 12:
        a = nrng.random(shape).astype(dtype)
        if a.size and rnd.randrange(4) == 0:
            a.flat[rnd.randrange(a.size)] = rnd.choice(SPECIAL) if a.dtype.kind == "f" else 0
        return a
    if op == 12:
        return nrng.random(shape).astype(rnd.choice(
            [np.float64, np.float16, np.int32, np.uint32, np.int64, np.bool_, np.complex64, object]
        ))
    if op == 13:
        return nrng.random(shape).astype(np.dtype(dtype).newbyteorder(">"))
    if op == 14 and len(shape) == 2:
        return np.asfortranarray(nrng.random((shape[0], shape[1] + 1)).astype(dtype))[:, :shape[1]]
    if op == 15:
        big = nrng.random(tuple(2 * s + 1 for s in shape)).astype(dtype)
        return big[tuple(slice(None, None, 2) for _ in shape)][tuple(slice(0, s) for s in shape)]
    if op == 16:
        bad = list(shape)
        if bad:
            bad[rnd.randrange(len(bad))] += rnd.choice([-1, 1, 5])
        return nrng.random(tuple(max(0, s) for s in bad)).astype(dtype)
    if op == 17:
        return nrng.random(shape + (1,)).astype(dtype)
    if op == 18:
        return np.zeros((0,) + tuple(shape[1:]), dtype=dtype)
    if op == 19:
        a = nrng.random(shape).astype(dtype)
        a.flags.writeable = False
        return a
    if op == 20:
        return nrng.random(shape).astype(dtype).tolist()
    if op == 21:
        return np.full(shape, rnd.choice(SPECIAL), dtype=dtype)
    return rnd.choice([None, "x", 3, 2.5, (), [[]], {"a": 1}, np.float32(1.0)])


def weights(rnd, nrng, k, n):
    op = rnd.randrange(10)
    if op < 4:
        w = nrng.random(k) + 0.01
        return (w / w.sum()).astype(np.float32)
    if op == 4:
        w = nrng.random((n, k)).astype(np.float32) + np.float32(0.01)
        return w / w.sum(axis=1, keepdims=True)
    if op == 5:
        return [1.0 / k] * k
    if op == 6:
        return [rnd.choice(SPECIAL) for _ in range(k + rnd.choice([-1, 0, 1]))]
    return array(rnd, nrng, rnd.choice([(k,), (n, k), (k + 1,), (n + 1, k)]), np.float32)


def scalar(rnd):
    return rnd.choice(SPECIAL + [0.01, 0.05, 0.2, 1, 10 ** 40, -5, None, "0.1", np.float64(0.1)])


def indices(rnd, nrng, n, count):
    op = rnd.randrange(8)
    if op < 4:
        return nrng.integers(0, max(n, 1) + 2, size=count).astype(np.uint32)
    if op == 4:
        return np.array([0xFFFFFFFF, n, n - 1][: max(count, 1)], dtype=np.uint32)
    if op == 5:
        return nrng.integers(-5, n + 5, size=count)
    return array(rnd, nrng, (count,), np.uint32)


def blend_queries(rnd, nrng, blend, k, dim, n_points):
    for _ in range(rnd.randint(1, 4)):
        n = rnd.choice([0, 1, 2, 7, 33])
        w = weights(rnd, nrng, k, n)
        op = rnd.randrange(8)
        if op == 0:
            call(blend.point, w, array(rnd, nrng, (n, dim), np.float32), scalar(rnd))
        elif op == 1:
            call(blend.point_adaptive, w, array(rnd, nrng, (n, dim), np.float32),
                 scalar(rnd), scalar(rnd), scalar(rnd))
        elif op == 2:
            call(blend.range, w, array(rnd, nrng, (n, dim), np.float32),
                 array(rnd, nrng, (n, dim), np.float32))
        elif op == 3:
            call(blend.sample, w, indices(rnd, nrng, n_points, n))
        elif op == 4:
            call(blend.bandwidth, w, indices(rnd, nrng, n_points, n),
                 scalar(rnd), scalar(rnd), scalar(rnd))
        elif op == 5:
            call(blend.mean_mass, w)
        elif op == 6:
            side = rnd.choice([1, 2, 5, 16, 0, -1, 65536, 65537, 2 ** 31, 2 ** 63])
            res = [side if rnd.randrange(3) else rnd.choice([1, 3]) for _ in range(dim)]
            if rnd.randrange(8) == 0:
                res = res + [2]
            call(blend.splat, w, res, scalar(rnd), color=rnd.choice([True, False]))
        else:
            call(getattr, blend, rnd.choice(["k", "dim", "n", "has_color", "wrap", "composite"]))
            call(repr, blend)


def brdf_queries(rnd, nrng, brdf, k, n_points):
    for _ in range(rnd.randint(1, 3)):
        n = rnd.choice([0, 1, 4, 17])
        w = weights(rnd, nrng, k, n)
        op = rnd.randrange(3)
        if op == 0:
            call(brdf.eval, w, array(rnd, nrng, (n, 3), np.float64), array(rnd, nrng, (n, 3), np.float64))
        elif op == 1:
            call(brdf.pdf, w, array(rnd, nrng, (n, 3), np.float64), array(rnd, nrng, (n, 3), np.float64))
        else:
            call(brdf.sample, w, indices(rnd, nrng, n_points, n), array(rnd, nrng, (n, 5), np.float64))


def execute(rnd, nrng, ctx):
    """One execution; returns whether a blend was made."""
    if rnd.randrange(16) == 0:
        text = bytearray(rnd.choice(ctx.manifests))
        for _ in range(rnd.randint(1, 3)):
            if text:
                i = rnd.randrange(len(text))
                text[i:i + rnd.randrange(8)] = rnd.choice([b"", b"\"", b"[", b"=", b"0", b"-1", b"\n", b"nan"])
        p = os.path.join(ctx.scratch, "m.toml")
        with open(p, "wb") as f:
            f.write(text)
        call(otbake.archives, p)
    if rnd.randrange(16) == 0:
        n = rnd.choice([0, 1, 5])
        call(otbake.shade, rnd.choice(["additive", "alpha", "ink_on_white", "x", None]),
             array(rnd, nrng, (n,), np.float32), array(rnd, nrng, (n, 3), np.float32))
    name, proxy_b, maps_b = rnd.choice(ctx.cases)
    maps_b = list(maps_b)
    if rnd.randrange(6) == 0:
        if rnd.randrange(3) == 0:
            proxy_b = mutate_bytes(rnd, proxy_b)
        else:
            i = rnd.randrange(len(maps_b))
            maps_b[i] = mutate_bytes(rnd, maps_b[i])
    proxy = call(otbake.Proxy.open, source(rnd, proxy_b, ctx, "proxy"))
    maps = [call(otbake.Map.open, source(rnd, b, ctx, "map%d" % i)) for i, b in enumerate(maps_b)]
    if proxy is None or any(m is None for m in maps):
        return False
    call(repr, proxy)
    call(getattr, proxy, rnd.choice(["dim", "n"]))
    for m in maps:
        call(repr, m)
        call(getattr, m, rnd.choice(["dim", "n", "has_color", "mean_mass", "composite"]))
    op = rnd.randrange(12)
    if op == 0:
        maps = []
    elif op == 1:
        maps = maps + maps
    elif op == 2:
        _, other_p, other_m = rnd.choice(ctx.cases)
        other = call(otbake.Map.open, other_m[0])
        maps = maps + ([other] if other is not None else [])
    elif op == 3:
        maps = maps[:1] + [rnd.choice([proxy, None, 1, "map"])]
    elif op == 4:
        maps = tuple(maps)
    blend = call(otbake.Blend, proxy, maps)
    if blend is None:
        return False
    k, dim, n_points = blend.k, blend.dim, blend.n
    blend_queries(rnd, nrng, blend, k, dim, n_points)
    if dim == 3 and rnd.randrange(2) == 0:
        kw = rnd.choice([
            {"sigma": scalar(rnd)},
            {"adaptive": rnd.choice([None, (2.0, 0.001, 0.05), (scalar(rnd), scalar(rnd), scalar(rnd)), (1.0,), "x"])},
            {},
            {"sigma": 0.05, "adaptive": (2.0, 0.001, 0.05)},
        ])
        brdf = call(otbake.BrdfBlend, proxy, maps, **kw)
        if brdf is not None:
            brdf_queries(rnd, nrng, brdf, k, n_points)
    return True


def generators(seed, index):
    s = (seed * 1_000_003 + index) & ((1 << 64) - 1)
    return random.Random(s), np.random.default_rng(s)


def write_finding(seed, index, reason):
    d = os.path.join(FINDINGS, "python-%d-%d" % (seed, index))
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "reason.txt"), "w") as f:
        f.write(reason + "\n\nreplay: %s %s --replay %d %d\n" % (
            sys.executable, os.path.relpath(__file__, ROOT), index, seed))
    return d


def campaign(first, executions, seed, progress):
    # numpy's casting warnings (e.g. complex to float in `shade`) are not findings.
    warnings.simplefilter("ignore")
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))
    ctx = Context(load_cases(), load_manifests(), tempfile.mkdtemp(prefix="otbake-pyfuzz-"))
    findings = made = 0
    slowest = 0.0
    t0 = time.time()
    with open(progress, "r+b") as prog:
        index = first - 1
        for index in range(first, first + executions):
            prog.seek(0)
            prog.write(b"%020d" % index)
            prog.flush()
            rnd, nrng = generators(seed, index)
            t = time.time()
            try:
                made += execute(rnd, nrng, ctx)
            except BaseException as e:  # a finding: anything not in ALLOWED
                if isinstance(e, KeyboardInterrupt):
                    raise
                findings += 1
                d = write_finding(seed, index, "%s: %s\n\n%s" % (type(e).__name__, e, traceback.format_exc()))
                print("finding: execution %d (seed %d): %s: %s; written to %s" % (index, seed, type(e).__name__, e, d))
                if findings >= 20:
                    break
            slowest = max(slowest, time.time() - t)
            if (index + 1 - first) % 100_000 == 0:
                print("python: %d executions, %d findings, %.0f s" % (index + 1 - first, findings, time.time() - t0), flush=True)
    shutil.rmtree(ctx.scratch, ignore_errors=True)
    secs = time.time() - t0
    ran = index + 1 - first
    print("python: %d executions (from %d), seed %d: %d made a blend, %d findings, slowest %.1f ms, %.1f s (%.0f per second)" % (
        ran, first, seed, made, findings, slowest * 1e3, secs, ran / max(secs, 1e-9)))
    return 1 if findings else 0


def main(argv):
    if argv[:1] == ["--replay"]:
        index, seed = int(argv[1]), int(argv[2])
        ctx = Context(load_cases(), load_manifests(), tempfile.mkdtemp(prefix="otbake-pyfuzz-"))
        rnd, nrng = generators(seed, index)
        try:
            print("execution %d of seed %d: made a blend: %s" % (index, seed, execute(rnd, nrng, ctx)))
        finally:
            shutil.rmtree(ctx.scratch, ignore_errors=True)
        return 0
    if argv[:1] == ["--child"]:
        return campaign(int(argv[1]), int(argv[2]), int(argv[3]), argv[4])
    first = 0
    if argv[:1] == ["--first"]:
        first, argv = int(argv[1]), argv[2:]
    executions = int(argv[0]) if argv else 100_000
    seed = int(argv[1]) if len(argv) > 1 else 1
    fd, progress = tempfile.mkstemp(prefix="otbake-pyfuzz-progress-")
    os.write(fd, b"%020d" % first)
    os.close(fd)
    r = subprocess.run([sys.executable, __file__, "--child", str(first), str(executions), str(seed), progress])
    with open(progress, "rb") as f:
        index = int(f.read(20) or b"0")
    os.remove(progress)
    if r.returncode >= 0:
        return r.returncode
    d = write_finding(seed, index, "crash: the process was killed by signal %d" % -r.returncode)
    print("finding: execution %d (seed %d) killed the process (signal %d); written to %s" % (
        index, seed, -r.returncode, d))
    return 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

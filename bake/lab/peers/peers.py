#!/usr/bin/env python3
"""Peer OT solvers for `otbake bench`: POT's exact `ot.emd`, POT's log-domain `ot.sinkhorn`,
GeomLoss's multiscale Sinkhorn and POT's BSP-OT bijection, run on the bench's own point clouds.

The bench drives this script (bake/lab/src/bench/peers.rs); it is not needed by CI or by the
baker. Install the tools into any Python 3 environment, e.g.

    python3 -m venv /tmp/peers && /tmp/peers/bin/pip install numpy pot
    /tmp/peers/bin/pip install --index-url https://download.pytorch.org/whl/cpu torch
    /tmp/peers/bin/pip install geomloss pykeops

and point the bench at it: `OTBAKE_PEERS_PYTHON=/tmp/peers/bin/python otbake bench`.

    peers.py list
        JSON {"tools": [...], "missing": {tool: reason}} on stdout.
    peers.py run TOOL --dim D --source S --target T --out M
        S, T: little-endian f32, point-major, n x D. Writes the mapped source points (the image of
        source point i at row i) to M the same way, and prints JSON {"seconds": s, "detail": "..."}
        with the solve's own wall time (loading and writing excluded). Exit status 1 and a message
        on stderr when the tool fails.

Maps: emd and BSP-OT give permutations (each source point goes to one target sample); Sinkhorn
(POT and GeomLoss) gives the barycentric projection of its entropic plan. The blur of both Sinkhorn
peers is otbake's default: 1.5 mean point spacings (V/n)^(1/d) of the target's bounding box in 2D,
1.0 in 3D; epsilon = blur^2 on the cost |x - y|^2.
"""

import json
import sys
import time

TOOLS = ["pot_emd", "pot_sinkhorn", "geomloss", "bsp_ot"]


def available():
    """Which tools import, and why the others do not."""
    tools, missing = [], {}
    try:
        import numpy  # noqa: F401
        import ot  # noqa: F401

        tools += ["pot_emd", "pot_sinkhorn"]
        if hasattr(ot, "bsp"):
            tools.append("bsp_ot")
        else:
            missing["bsp_ot"] = "this POT has no ot.bsp (POT >= 0.9.6 has)"
    except ImportError as e:
        for t in ("pot_emd", "pot_sinkhorn", "bsp_ot"):
            missing[t] = f"{e} (pip install numpy pot)"
    try:
        import geomloss  # noqa: F401
        import torch  # noqa: F401

        tools.append("geomloss")
    except ImportError as e:
        missing["geomloss"] = f"{e} (pip install torch geomloss pykeops)"
    return [t for t in TOOLS if t in tools], missing


def blur_of(y, dim):
    import numpy as np

    n = len(y)
    extent = np.maximum(y.max(axis=0) - y.min(axis=0), 1e-9)
    spacing = (float(np.prod(extent)) / n) ** (1.0 / dim)
    return (1.5 if dim <= 2 else 1.0) * spacing


def run_pot_emd(x, y, dim):
    import numpy as np
    import ot

    n = len(x)
    a = np.full(n, 1.0 / n)
    t = time.perf_counter()
    m = ot.dist(x, y)
    g = ot.emd(a, a, m, numItermax=100_000_000)
    perm = g.argmax(axis=1)
    seconds = time.perf_counter() - t
    return y[perm], seconds, "ot.emd, permutation from the plan's row maxima"


def run_pot_sinkhorn(x, y, dim):
    import numpy as np
    import ot

    n = len(x)
    a = np.full(n, 1.0 / n)
    blur = blur_of(y, dim)
    t = time.perf_counter()
    m = ot.dist(x, y)
    g = ot.sinkhorn(a, a, m, blur * blur, method="sinkhorn_log", numItermax=1000, stopThr=1e-6)
    mapped = (g @ y) / g.sum(axis=1, keepdims=True)
    seconds = time.perf_counter() - t
    return mapped, seconds, f"ot.sinkhorn log-domain, reg = blur^2, blur {blur:.3e}, barycentric"


def run_geomloss(x, y, dim):
    import numpy as np
    import torch
    from geomloss import SamplesLoss

    try:
        import pykeops  # noqa: F401

        backend = "multiscale"
    except ImportError:
        backend = "tensorized"
    blur = blur_of(y, dim)
    xt = torch.tensor(x, dtype=torch.float64, requires_grad=True)
    yt = torch.tensor(y, dtype=torch.float64)
    # GeomLoss's cost for p = 2 is |x - y|^2 / 2 and its eps is blur^p: blur / sqrt(2) gives
    # eps = blur^2 / 2 on that cost, i.e. blur^2 on |x - y|^2, as otbake's.
    loss = SamplesLoss("sinkhorn", p=2, blur=blur / 2**0.5, scaling=0.5, backend=backend)
    t = time.perf_counter()
    value = loss(xt, yt)
    (grad,) = torch.autograd.grad(value, [xt])
    # d loss / d x_i = a_i (x_i - T(x_i)) with a_i = 1/n.
    mapped = (xt - len(x) * grad).detach().numpy()
    seconds = time.perf_counter() - t
    return mapped, seconds, f"SamplesLoss sinkhorn {backend}, scaling 0.5, blur {blur:.3e}, gradient map"


def run_bsp_ot(x, y, dim):
    import numpy as np
    import ot

    plans = 16
    t = time.perf_counter()
    result = ot.bsp.compute_bspot_bijection(x, y, plans)
    perm = np.asarray(result[1] if isinstance(result, tuple) else result)
    seconds = time.perf_counter() - t
    return y[perm], seconds, f"ot.bsp.compute_bspot_bijection, {plans} plans"


RUN = {
    "pot_emd": run_pot_emd,
    "pot_sinkhorn": run_pot_sinkhorn,
    "geomloss": run_geomloss,
    "bsp_ot": run_bsp_ot,
}


def main(argv):
    if len(argv) >= 1 and argv[0] == "list":
        tools, missing = available()
        print(json.dumps({"tools": tools, "missing": missing}))
        return 0
    if len(argv) < 2 or argv[0] != "run" or argv[1] not in RUN:
        print(f"usage: peers.py list | peers.py run {{{','.join(TOOLS)}}} --dim D "
              "--source S --target T --out M", file=sys.stderr)
        return 2
    tool = argv[1]
    opts = dict(zip(argv[2::2], argv[3::2]))
    import numpy as np

    dim = int(opts["--dim"])
    x = np.fromfile(opts["--source"], dtype="<f4").astype(np.float64).reshape(-1, dim)
    y = np.fromfile(opts["--target"], dtype="<f4").astype(np.float64).reshape(-1, dim)
    if len(x) != len(y):
        print(f"source has {len(x)} points, target {len(y)}", file=sys.stderr)
        return 1
    try:
        mapped, seconds, detail = RUN[tool](x, y, dim)
    except Exception as e:  # a failing tool is a bench row, not a crash
        print(f"{tool} failed: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    mapped = np.ascontiguousarray(mapped, dtype="<f4")
    if mapped.shape != x.shape or not np.all(np.isfinite(mapped)):
        print(f"{tool} returned {mapped.shape} or non-finite points", file=sys.stderr)
        return 1
    tmp = opts["--out"] + ".tmp"
    mapped.tofile(tmp)
    import os

    os.replace(tmp, opts["--out"])
    print(json.dumps({"seconds": seconds, "detail": detail}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

"""otbake from Python: bake optimal-transport maps of appearance assets, open the archives, and
blend them on numpy arrays (point, range, sample and splat queries; BRDF eval, pdf and sample).

    import numpy as np, otbake
    report = otbake.bake("manifests/shapes-small.toml")        # the bake report, a dict
    blend = otbake.open_manifest("manifests/shapes-small.toml")  # bakes what is missing, opens it
    pts = np.random.default_rng(0).random((1000, 2), dtype=np.float32)
    density, mass, color = blend.point([0.25, 0.25, 0.25, 0.25], pts, sigma=0.01)
    prepared = blend.prepare([0.25, 0.25, 0.25, 0.25])          # mixed once: no weights per query
    density, color = prepared.splat((256, 256), sigma=0.002)

Every function checks its arrays (shape, dtype, C-contiguity) and weights, and raises an
:class:`otbake.Error` subclass naming the argument. Batch calls release the GIL. The Mitsuba 3
plugins are in :mod:`otbake.mitsuba`.
"""

import json as _json

from ._errors import (
    ArchiveError,
    ArgumentError,
    BakeError,
    Error,
    ManifestError,
    QueryError,
)
from ._native import Blend, BrdfBlend, Map, Prepared, Proxy, __version__
from . import _native

__all__ = [
    "ArchiveError",
    "ArgumentError",
    "BakeError",
    "Blend",
    "BrdfBlend",
    "Error",
    "ManifestError",
    "Map",
    "Prepared",
    "Proxy",
    "QueryError",
    "bake",
    "open_manifest",
    "shade",
]


def bake(manifest, force=False, store=None):
    """Bakes the manifest at ``manifest`` (a path): only the products that are not current, or
    all of them with ``force``; ``store`` overrides the store directory. Returns the report as a
    dict ``{"products": [{"name", "path", "status", "seconds", "detail"}]}``. Raises
    :class:`ManifestError` for an invalid manifest and :class:`BakeError` (with ``.report``) when
    a product failed."""
    text, failure = _native.bake(str(manifest), force, None if store is None else str(store))
    report = _json.loads(text)
    if failure is not None:
        raise BakeError(failure, report)
    return report


def open_manifest(manifest, brdf=False, bake_first=True, **brdf_kernel):
    """The blend of a manifest's inputs: bakes what is not current (unless ``bake_first`` is
    False), opens the proxy and the maps in manifest order, and returns a :class:`Blend` — or a
    :class:`BrdfBlend` with ``brdf=True`` (``brdf_kernel``: ``sigma=`` or ``adaptive=``). The
    input names are in the returned object's ``names`` attribute of :func:`archives`."""
    if bake_first:
        bake(manifest)
    proxy, maps = archives(manifest)
    opened = [Map.open(path) for _, path in maps]
    if brdf:
        return BrdfBlend(Proxy.open(proxy), opened, **brdf_kernel)
    return Blend(Proxy.open(proxy), opened)


def archives(manifest):
    """``(proxy_path, [(input_name, map_path), ...])`` of a manifest (nothing is baked or read)."""
    proxy, maps = _native.manifest_archives(str(manifest))
    return proxy, list(maps)


def shade(composite, mass, color):
    """Pixels as ``otbake blend`` writes them (RGBA, float32 ``(..., 4)``) from blended ``mass``
    ``(...)`` and premultiplied ``color`` ``(..., 3)`` under the maps' ``composite`` rule
    (``Blend.composite``): "additive" (color on black), "alpha" (color over a transparent
    background) or "ink_on_white"."""
    import numpy as np

    mass = np.asarray(mass, dtype=np.float32)
    color = np.asarray(color, dtype=np.float32)
    out = np.empty(mass.shape + (4,), dtype=np.float32)
    if composite == "additive":
        out[..., :3] = color
        out[..., 3] = 1.0
    elif composite == "alpha":
        safe = np.where(mass > 0, mass, 1.0)
        inv = np.where(mass > 0, np.float32(1.0) / safe, 0.0).astype(np.float32)
        out[..., :3] = color * inv[..., None]
        out[..., 3] = np.clip(mass, 0.0, 1.0)
    elif composite == "ink_on_white":
        bg = np.float32(1.0) - np.clip(mass, 0.0, 1.0)
        out[..., :3] = color + bg[..., None]
        out[..., 3] = 1.0
    else:
        raise ArgumentError(
            f"composite is {composite!r}: use 'additive', 'alpha' or 'ink_on_white'"
        )
    return out

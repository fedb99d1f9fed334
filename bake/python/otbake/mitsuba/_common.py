"""What the plugins share: reading properties, and moving Mitsuba values to numpy and back in
both scalar variants (one value per call) and JIT variants (whole wavefronts per call)."""

import numpy as np

import otbake


def mi():
    import mitsuba

    return mitsuba


def vectorize():
    """Lets the plugins run in a JIT variant (``llvm_ad_rgb``): Dr.Jit then calls Python with
    evaluated arrays instead of symbolic variables, which numpy cannot read."""
    import drjit as dr

    for flag in ("SymbolicLoops", "SymbolicCalls", "SymbolicConditionals"):
        dr.set_flag(getattr(dr.JitFlag, flag), False)


def is_scalar():
    return mi().variant().startswith("scalar")


def arr(x, dtype=np.float32):
    """A Mitsuba Float (a Python float in scalar variants, a Dr.Jit array otherwise) as a 1-D
    numpy array."""
    return np.atleast_1d(np.asarray(x, dtype=dtype))


def to_float(a):
    """A 1-D numpy array as a Mitsuba Float."""
    m = mi()
    if is_scalar():
        return float(a[0])
    return m.Float(np.ascontiguousarray(a, dtype=np.float32))


def to_color(rgb):
    """An (n, 3) numpy array as a Mitsuba Color3f."""
    m = mi()
    if is_scalar():
        return m.Color3f(float(rgb[0, 0]), float(rgb[0, 1]), float(rgb[0, 2]))
    return m.Color3f(to_float(rgb[:, 0]), to_float(rgb[:, 1]), to_float(rgb[:, 2]))


def to_vector(v):
    """An (n, 3) numpy array as a Mitsuba Vector3f."""
    m = mi()
    if is_scalar():
        return m.Vector3f(float(v[0, 0]), float(v[0, 1]), float(v[0, 2]))
    return m.Vector3f(to_float(v[:, 0]), to_float(v[:, 1]), to_float(v[:, 2]))


def vec3(v, dtype=np.float64):
    """A Mitsuba Vector3f/Point3f as an (n, 3) numpy array."""
    return np.ascontiguousarray(np.stack([arr(v.x, dtype), arr(v.y, dtype), arr(v.z, dtype)], axis=1))


def prop(props, name, default=None, required=False):
    """A property, or ``default``; a clear error when a required one is missing."""
    if name in props:
        return props[name]
    if required:
        raise otbake.ArgumentError(f"the otbake plugin needs the property {name!r}")
    return default


def parse_weights(text, k, plugin):
    """``"a,b,..."`` (or a sequence such as an RGB property) as k float32 weights."""
    try:
        values = str(text).split(",") if isinstance(text, str) else list(text)
        w = np.array([float(v) for v in values], dtype=np.float32)
    except ValueError:
        raise otbake.ArgumentError(
            f"{plugin}: weights {text!r} is not a comma-separated list of numbers (or a list, or a texture)"
        ) from None
    if w.shape != (k,):
        raise otbake.ArgumentError(
            f"{plugin}: weights {text!r} has {w.size} values for {k} inputs: give one per input"
        )
    return w


def open_blend(props, plugin, brdf=False, **kernel):
    """The blend of the manifest named by the ``manifest`` property (baked if not current)."""
    manifest = prop(props, "manifest", required=True)
    return otbake.open_manifest(str(manifest), brdf=brdf, **kernel)

"""Mitsuba 3 plugins that evaluate otbake blends through the runtime (Mitsuba 3.9).

Call :func:`register` once after ``mitsuba.set_variant(...)``; it registers, for that variant,

* the texture ``otbake_blend``: a 2D blend evaluated at the shading point's uv (weights fixed, or
  from a weight texture), shaded as ``otbake blend`` shades its pixels;
* the BSDF ``otbake_brdf``: a BRDF blend evaluated through the runtime, importance-sampled and
  given its pdf (see :mod:`otbake.mitsuba.bsdf`);

and :func:`volume` makes the volume that serves a 3D blend's density to a ``heterogeneous``
medium (Mitsuba has no registry for Python volumes: pass the object itself as ``sigma_t``).

``scalar_rgb`` calls the plugins once per shading point; ``llvm_ad_rgb`` works too when Dr.Jit
hands Python whole wavefronts: call :func:`vectorize` (it turns the symbolic loop, call and
conditional JIT flags off, so that numpy may read the arrays).
"""

from ._common import vectorize
from .texture import register_texture
from .bsdf import register_bsdf
from .volume import volume

__all__ = ["register", "vectorize", "volume"]


def register():
    """Registers ``otbake_blend`` and ``otbake_brdf`` for the current Mitsuba variant."""
    register_texture()
    register_bsdf()

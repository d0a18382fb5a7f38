"""bandelets: surface and normal-map compression with second-generation geometric bandelets.

An implementation of Peyre and Mallat, "Surface Compression with Geometric Bandelets"
(SIGGRAPH 2005): a 2D wavelet transform whose detail subbands are re-transformed along
the direction of their geometry in every square of a best quadtree, followed by
quantization, context-modelled arithmetic coding and a .bdl file.

>>> import bandelets, numpy as np
>>> data = bandelets.encode(np.random.default_rng(0).random((64, 64)), bpp=2.0)
>>> bandelets.decode(data).shape
(64, 64)
"""

from importlib import import_module
from typing import TYPE_CHECKING

from .runtime import kernelcache as _kernelcache

__version__ = "0.1.0"

# Before any kernel is loaded: those cached by an earlier install may be stale (kernelcache).
_kernelcache.purge_stale_kernels()

# The codec pulls in numba; it is imported on first use so that the command line starts fast.
_HOME = {
    "Bandelets": "transform.bandelets",
    "EncodeOptions": "codec.options",
    "FormatError": "format.header",
    "Kind": "format.header",
    "Layout": "format.header",
    "batch": "apps.batch",
    "check": "codec.decoder",
    "decode": "codec.decoder",
    "encode": "codec.encoder",
    "forward": "search.basis",
    "inverse": "transform.bandelets",
}
__all__ = [
    "Bandelets",
    "EncodeOptions",
    "FormatError",
    "Kind",
    "Layout",
    "batch",
    "check",
    "decode",
    "encode",
    "forward",
    "inverse",
]

if TYPE_CHECKING:  # what the lazy loading below gives, for type checkers and IDEs
    from .apps.batch import batch
    from .codec.decoder import check, decode
    from .codec.encoder import encode
    from .codec.options import EncodeOptions
    from .format.fields import FormatError, Kind, Layout
    from .search.basis import forward
    from .transform.bandelets import Bandelets, inverse


def __getattr__(name: str):
    if name in _HOME:
        return getattr(import_module(f".{_HOME[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return [*__all__, "__version__"]

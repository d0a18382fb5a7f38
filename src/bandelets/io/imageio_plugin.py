"""An imageio v3 plugin for .bdl files: ``imageio.v3.imread("x.bdl")`` and ``imwrite("x.bdl", array)``.

imageio (2.x) finds plugins in its own ``imageio.config.known_plugins`` and has no entry-point
discovery, so this module registers the plugin and the ``.bdl`` extension when it is imported::

    import imageio.v3 as iio
    import bandelets.io.imageio_plugin  # noqa: F401  (registers .bdl)

    iio.imwrite("normals.bdl", normals, kind="normal-map", bpp=1)
    decoded = iio.imread("normals.bdl")

``imread`` returns what :func:`bandelets.decode` returns (float64, a normal map renormalised);
``imwrite`` takes the keyword arguments of :func:`bandelets.encode` (default 1 bpp) and writes a
file, or returns the bytes for ``"<bytes>"``. The ``imageio`` extra installs imageio.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from imageio.config import known_plugins
from imageio.config.extensions import FileExtension, extension_list, known_extensions
from imageio.config.plugins import PluginConfig
from imageio.core.request import URI_BYTES, InitializationError, Request
from imageio.core.v3_plugin_api import ImageProperties, PluginV3

from ..codec.decoder import check, decode
from ..codec.encoder import encode
from ..format.container import header_of
from ..format.fields import Kind, Layout

__all__ = ["BandeletsPlugin", "register"]


class BandeletsPlugin(PluginV3):
    """Reads and writes one .bdl image (the plugin imageio instantiates per request)."""

    def __init__(self, request: Request) -> None:
        super().__init__(request)
        self._data = b""
        if request.mode.io_mode == "r":
            self._data = request.get_file().read()
            if not check(self._data):
                raise InitializationError("not a .bdl file")
        elif (request.extension or request.format_hint) != ".bdl":
            raise InitializationError("bandelets writes .bdl files only")

    def read(self, *, index: int | None = None, **options: Any) -> np.ndarray:
        """The decoded image; ``options`` of :func:`bandelets.decode` (``restore``, limits)."""
        if index not in (None, 0, Ellipsis):
            raise IndexError(f"a .bdl file holds one image, not image {index}")
        image = decode(self._data, **options)
        return image[None] if index is Ellipsis else image

    def iter(self, **options: Any):
        yield self.read(**options)

    def write(self, ndimage: np.ndarray, *, is_batch: bool = False, **options: Any) -> bytes | None:
        """Encode ``ndimage`` with the options of :func:`bandelets.encode` (default ``bpp=1``)."""
        if is_batch:
            raise ValueError("a .bdl file holds one image")
        if not {"bpp", "threshold", "psnr", "max_angle"} & set(options):
            options["bpp"] = 1.0
        data = encode(ndimage, **options)
        if self.request._uri_type == URI_BYTES:
            return data
        self.request.get_file().write(data)
        return None

    def properties(self, *, index: int | None = None) -> ImageProperties:
        header = header_of(self._data)
        channels = header.channels
        if header.kind == Kind.NORMAL_MAP and header.layout != Layout.XY:
            channels = 3  # z is rebuilt when only x, y were coded
        shape = (header.height, header.width) + ((channels,) if channels > 1 else ())
        return ImageProperties(shape=shape, dtype=np.dtype(np.float64), n_images=None, is_batch=False)

    def metadata(self, *, index: int | None = None, exclude_applied: bool = True) -> dict:
        """The header's fields (:class:`bandelets.format.header.Header`)."""
        header = header_of(self._data)
        return dict(vars(header))


def register() -> None:
    """Make imageio choose this plugin for ``.bdl`` files (done on import; idempotent)."""
    known_plugins["bandelets"] = PluginConfig(
        name="bandelets", class_name="BandeletsPlugin", module_name="bandelets.io.imageio_plugin"
    )
    if not any("bandelets" in e.priority for e in known_extensions.get(".bdl", [])):
        extension = FileExtension(
            extension=".bdl",
            priority=["bandelets"],
            name="bandelets",
            description="Geometric bandelet compression of images, normal maps and geometry images",
        )
        known_extensions.setdefault(".bdl", []).insert(0, extension)
        extension_list.append(extension)


register()

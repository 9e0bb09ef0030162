"""The bound on an image's size (``--max-pixels``) and channels, checked on what a file's header declares
before anything is decoded or allocated — images and depth maps alike.
"""
from __future__ import annotations

from contextlib import contextmanager
from contextvars import ContextVar

from fogsim.errors import InputError
from fogsim.io.headers import ImageHeader

__all__ = ["MAX_CHANNELS", "MAX_FILE_BYTES_PER_PIXEL", "MAX_PIXELS", "check_declared", "max_pixels_now",
           "pixel_bound", "pixel_limit_problem"]


#: Default bound on an image's size, width × height, for ``fogsim render`` and ``fogsim fog``
#: (about 8192 × 4883; the Waymo front camera is 2.5 MP): a frame's arrays, its fog levels and
#: Cycles' buffers grow with it; raise it with ``--max-pixels`` when a larger image is meant.
MAX_PIXELS = 40_000_000


def pixel_limit_problem(width: int, height: int, max_pixels: int, action: str = "render") -> str | None:
    """Why a ``width`` × ``height`` image is refused under ``max_pixels`` (``--max-pixels``), or None;
    ``action`` is what raising the flag would let happen ("render", "fog")."""
    if width * height > max_pixels:
        return (f"{width}×{height} = {width * height / 1e6:.1f} MP is above the limit of {max_pixels / 1e6:g} MP "
                f"(--max-pixels {max_pixels}); raise --max-pixels to {action} it")
    return None


#: the most channels a decoded image may declare (an RGBA PNG has 4; a multi-layer EXR render ≈ 10)
MAX_CHANNELS = 32
#: the most bytes an image file may take per pixel of the bound (16: RGBA float32 stored uncompressed)
MAX_FILE_BYTES_PER_PIXEL = 16
_PIXEL_BOUND: ContextVar[int] = ContextVar("fogsim_max_pixels", default=MAX_PIXELS)


@contextmanager
def pixel_bound(max_pixels: int):
    """Within the block, every image and depth file is read under ``max_pixels`` (``--max-pixels``)
    instead of :data:`MAX_PIXELS` (the readers decode before the job sees the image)."""
    token = _PIXEL_BOUND.set(int(max_pixels))
    try:
        yield
    finally:
        _PIXEL_BOUND.reset(token)


def max_pixels_now() -> int:
    """The pixel bound in force (:func:`pixel_bound`, else :data:`MAX_PIXELS`)."""
    return _PIXEL_BOUND.get()


def check_declared(header: ImageHeader | None, source) -> None:
    """Refuse an image whose header declares more pixels than :func:`max_pixels_now` or more than
    :data:`MAX_CHANNELS` channels — before anything is decoded or allocated."""
    if header is None:
        return
    bound = max_pixels_now()
    if pixel_limit_problem(header.width, header.height, bound):
        raise InputError(source, f"its {header.kind.upper()} header declares {header.width}×{header.height} = "
                                 f"{header.pixels / 1e6:.1f} MP, above the limit of {bound / 1e6:g} MP (--max-pixels "
                                 f"{bound}): refused before decoding; raise --max-pixels to read it")
    if header.channels > MAX_CHANNELS:
        raise InputError(source, f"its {header.kind.upper()} header declares {header.channels} channels (at most "
                                 f"{MAX_CHANNELS})")

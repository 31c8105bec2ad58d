"""Linear radiance to the 8-bit RGBA a browser draws, the way the toolkit's PNGs are made
(toolkit.core.images.to_srgb8: clamp to [0, 1], then the sRGB curve), so the live image and
`python -m toolkit render`'s PNG of the same samples look the same (within one level of 255).

The curve is read from a table of LEVELS entries instead of computed per pixel: a power per
channel took 10 ms of a 256x256 frame, a tenth of the samples a pass renders on a 2-core CPU."""
import numpy as np

from toolkit.core.images import to_srgb8

LEVELS = 1 << 14      # steps of linear [0, 1]: 0.2 of an 8-bit level each where the curve is steepest
_CURVE = to_srgb8(np.linspace(0.0, 1.0, LEVELS))


def to_rgba(image, exposure=1.0):
    """(H, W, 3) linear RGB -> (H, W, 4) uint8 sRGB with alpha 255, top row first."""
    x = np.nan_to_num(np.asarray(image, np.float32) * np.float32(exposure), nan=0.0, posinf=1.0)
    index = (np.clip(x, 0.0, 1.0) * (LEVELS - 1) + 0.5).astype(np.int32)
    rgba = np.empty(x.shape[:2] + (4,), np.uint8)
    rgba[..., :3] = _CURVE[index]
    rgba[..., 3] = 255
    return rgba


def packed_for_bokeh(rgba):
    """(H, W, 4) uint8, top row first -> (H, W) uint32 as Bokeh's image_rgba wants it: one int
    per pixel, and the bottom row first (a plot's y axis points up)."""
    return np.ascontiguousarray(rgba[::-1]).view(np.uint32).reshape(rgba.shape[:2])

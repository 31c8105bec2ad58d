"""Linear radiance to the 8-bit RGBA a browser draws, the same way the toolkit's PNGs are made
(toolkit.core.images.to_srgb8: clamp to [0, 1], then the sRGB curve), so the live image and
`python -m toolkit render`'s PNG of the same samples look the same."""
import numpy as np

from toolkit.core.images import to_srgb8


def to_rgba(image, exposure=1.0):
    """(H, W, 3) linear RGB -> (H, W, 4) uint8 sRGB with alpha 255, top row first."""
    rgb = to_srgb8(np.asarray(image, np.float64) * exposure)
    alpha = np.full(rgb.shape[:2] + (1,), 255, np.uint8)
    return np.concatenate([rgb, alpha], axis=-1)


def packed_for_bokeh(rgba):
    """(H, W, 4) uint8, top row first -> (H, W) uint32 as Bokeh's image_rgba wants it: one int
    per pixel, and the bottom row first (a plot's y axis points up)."""
    return np.ascontiguousarray(rgba[::-1]).view(np.uint32).reshape(rgba.shape[:2])

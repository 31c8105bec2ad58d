"""Image files through OpenImageIO: linear float32 EXR and an sRGB 8-bit PNG beside it."""
from pathlib import Path

import numpy as np


def read_exr(path):
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(str(path))
    if buf.has_error:
        raise OSError(f"{path}: {buf.geterror()}")
    pixels = np.asarray(buf.get_pixels(oiio.FLOAT), np.float32)
    return pixels[..., :3]


def write_image(path, image):
    """Write float32 linear `image` (H,W,3) to path (.exr) and, for .exr, an sRGB PNG beside it."""
    import OpenImageIO as oiio
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    image = np.ascontiguousarray(image, np.float32)
    h, w, c = image.shape
    if path.suffix.lower() == ".png":
        return _write(oiio, path, to_srgb8(image), oiio.UINT8)
    _write(oiio, path, image, oiio.FLOAT)
    png = path.with_suffix(".png")
    _write(oiio, png, to_srgb8(image), oiio.UINT8)
    return path


def _write(oiio, path, pixels, fmt):
    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(str(path))
    if out is None:
        raise OSError(f"{path}: OpenImageIO cannot write this format: {oiio.geterror()}")
    out.open(str(path), oiio.ImageSpec(w, h, c, fmt))
    out.write_image(pixels)
    out.close()
    return path


def to_srgb8(image):
    x = np.clip(np.nan_to_num(image, nan=0.0, posinf=1.0), 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (srgb * 255 + 0.5).astype(np.uint8)

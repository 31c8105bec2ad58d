"""Image files through OpenImageIO: linear float32 EXR and an sRGB 8-bit PNG beside it."""
import os
import tempfile
from pathlib import Path

import numpy as np
import OpenImageIO as oiio


def _oiio_name(path):
    """The file name as OpenImageIO takes it: text only (toolkit/core/validate.py utf8_path checks
    the names given on the command line before any work; this catches the others)."""
    name = str(path)
    try:
        name.encode("utf-8")
    except UnicodeEncodeError:
        raise OSError(f"{os.fsencode(name).decode('utf-8', 'backslashreplace')}: the path is not valid UTF-8, "
                      "which OpenImageIO cannot open") from None
    return name


def read_exr(path):
    """(H, W, 3) float32 pixels; OSError naming the problem for a missing, truncated or corrupt file."""
    file = oiio.ImageInput.open(_oiio_name(path))
    if file is None:
        raise OSError(f"{path}: {oiio.geterror() or 'cannot open the image'}")
    try:
        pixels = file.read_image(oiio.FLOAT)     # None when any part is missing or corrupt
        if pixels is None:
            raise OSError(f"{path}: {file.geterror() or 'cannot read the image'}")
    finally:
        file.close()
    pixels = np.asarray(pixels, np.float32)
    if pixels.ndim != 3 or pixels.shape[2] < 3:
        raise OSError(f"{path}: expected an RGB image, got shape {pixels.shape}")
    return pixels[..., :3]


def write_image(path, image):
    """Write float32 linear `image` (H,W,3) to path: .exr, with an sRGB 8-bit .png beside it,
    or .png alone (sRGB 8-bit). Returns the paths written.

    Each file is written to a temporary file in the same folder, every result checked, then
    renamed over the old one: a failed write (disk full, no permission) raises OSError naming
    the reason and leaves any old file untouched."""
    path = Path(_oiio_name(path))
    suffix = path.suffix.lower()
    if suffix not in (".exr", ".png"):
        raise OSError(f"{path}: unsupported image type {path.suffix!r}; use .exr or .png")
    path.parent.mkdir(parents=True, exist_ok=True)
    image = np.ascontiguousarray(image, np.float32)
    files = [(path, to_srgb8(image), oiio.UINT8)] if suffix == ".png" else \
        [(path, image, oiio.FLOAT), (path.with_suffix(".png"), to_srgb8(image), oiio.UINT8)]
    temporary = []
    try:
        for target, pixels, fmt in files:
            temporary.append(_write_temporary(oiio, target, pixels, fmt))
        for (target, _, _), tmp in zip(files, temporary):
            os.replace(tmp, target)
    finally:
        for tmp in temporary:
            if os.path.exists(tmp):
                os.unlink(tmp)
    return [target for target, _, _ in files]


def _write_temporary(oiio, target, pixels, fmt):
    """Write `pixels` to a new temporary file beside `target` (same suffix: OpenImageIO picks
    the format by it); returns its name, or raises OSError with OpenImageIO's reason."""
    try:
        fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.stem}.", suffix=target.suffix)
    except OSError as error:
        raise OSError(f"{target}: cannot write there: {error.strerror or error}") from None
    os.close(fd)
    try:
        return _write_checked(oiio, target, tmp, pixels, fmt)
    except BaseException:
        if os.path.exists(tmp):      # on every error (a name OpenImageIO cannot take, Ctrl-C): no leftover
            os.unlink(tmp)
        raise


def _write_checked(oiio, target, tmp, pixels, fmt):
    """Write `pixels` to the file `tmp`, read it back and compare; returns tmp or raises OSError."""
    os.chmod(tmp, 0o666 & ~_umask())     # as an ordinary new file (mkstemp makes it private)
    h, w, c = pixels.shape
    out = oiio.ImageOutput.create(tmp)
    ok = out is not None and out.open(tmp, oiio.ImageSpec(w, h, c, fmt))
    ok = ok and out.write_image(pixels)
    reason = (out.geterror() if out is not None else "") or oiio.geterror()
    ok = out is not None and out.close() and ok
    reason = reason or (out.geterror() if out is not None else "") or oiio.geterror()
    if ok:
        # OpenImageIO does not report every failed write (a full disk can leave a truncated file
        # and a success), so the file is read back and compared before it replaces anything.
        file = oiio.ImageInput.open(tmp)
        back = file.read_image(pixels.dtype == np.uint8 and oiio.UINT8 or oiio.FLOAT) if file else None
        reason = "" if file is None else file.geterror()
        if file is not None:
            file.close()
        ok = back is not None and np.array_equal(np.asarray(back).reshape(pixels.shape), pixels)
        reason = reason or oiio.geterror() or "the file read back differs from the image (disk full?)"
    if not ok:
        raise OSError(f"{target}: cannot write the image: {reason or 'unknown error'}")
    with open(tmp, "rb") as f:     # on disk before the rename makes it the only copy
        os.fsync(f.fileno())
    return tmp


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def to_srgb8(image):
    x = np.clip(np.nan_to_num(image, nan=0.0, posinf=1.0), 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (srgb * 255 + 0.5).astype(np.uint8)


def write_atomically(path, write):
    """Write a file that is never seen half-written: `write(tmp)` writes a temporary file beside
    `path`, which is then synced and renamed over `path`. A failed write raises OSError naming the
    file and leaves any old file intact (as write_image does for images). Returns `path`."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix)
    except OSError as error:
        raise OSError(f"{path}: cannot write there: {error.strerror or error}") from None
    os.close(fd)
    try:
        os.chmod(tmp, 0o666 & ~_umask())
        write(tmp)
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as error:
        raise OSError(f"{path}: cannot write the file: {error.strerror or error}") from None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path

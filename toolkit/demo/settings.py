"""What the viewer chooses (techniques, scene, resolution, lanes, seed), checked. The page's
choices arrive from the browser, so every value is checked here as untrusted input, with a
message the page shows; the command line's go through the same checks before the server starts."""
from dataclasses import dataclass, replace

from toolkit.core.validate import InputError
from toolkit.core.config import checked_lanes
from toolkit.techniques import TECHNIQUES

MOST_TECHNIQUES = 3          # side by side
RESOLUTIONS = ((64, 64), (128, 128), (256, 256), (512, 512))
LARGEST = 1024               # a live view larger than this converges too slowly to watch
DEFAULT_TECHNIQUES = ("pt_naive", "pt_inplace_regen", "pt_compact_regen")


@dataclass(frozen=True)
class Settings:
    techniques: tuple = DEFAULT_TECHNIQUES
    scene: str = "cornell_box"      # a key of SceneChoices
    resolution: tuple = (128, 128)
    lanes: str = None               # "on", "off" or None (the device's default); Intel's CPU runtime only
    seed: int = 0

    def changed(self, **changes):
        """These settings with `changes`, each checked (InputError names the bad one)."""
        return checked(replace(self, **changes))


def checked(settings):
    techniques = settings.techniques
    if isinstance(techniques, str) or not isinstance(techniques, (list, tuple)):
        raise InputError(f"techniques must be a list of names, got {str(techniques)[:80]!r}")
    techniques = tuple(dict.fromkeys(techniques))          # each once, in the order chosen
    unknown = [t for t in techniques if not isinstance(t, str) or t not in TECHNIQUES]
    if unknown:
        raise InputError(f"unknown technique {str(unknown[0])[:80]!r}; known: {', '.join(TECHNIQUES)}")
    if not 1 <= len(techniques) <= MOST_TECHNIQUES:
        raise InputError(f"choose 1 to {MOST_TECHNIQUES} techniques to show side by side, not {len(techniques)}")
    return replace(settings, techniques=techniques, resolution=checked_resolution(settings.resolution),
                   lanes=checked_lanes(settings.lanes), seed=checked_seed(settings.seed))


def parse_resolution(text):
    """'WxH' -> (W, H), checked; an InputError with the reason otherwise."""
    try:
        width, height = (int(x) for x in str(text).lower().split("x"))
    except ValueError:
        raise InputError(f"resolution must be WIDTHxHEIGHT like 128x128, got {str(text)[:40]!r}") from None
    return checked_resolution((width, height))


def checked_resolution(resolution):
    try:
        width, height = (int(v) for v in resolution)
    except (TypeError, ValueError):
        raise InputError(f"resolution must be (width, height), got {str(resolution)[:40]!r}") from None
    if not (8 <= width <= LARGEST and 8 <= height <= LARGEST):
        raise InputError(f"resolution {width}x{height}: the live view renders 8x8 to {LARGEST}x{LARGEST}")
    return width, height


def checked_seed(seed):
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2 ** 32:
        raise InputError(f"seed must be a whole number 0 .. 2^32 - 1, got {str(seed)[:40]!r}")
    return seed

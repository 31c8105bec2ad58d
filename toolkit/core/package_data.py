"""Where the files installed beside the code live: the OpenCL sources (toolkit.cl), the bundled
scenes (toolkit.scenes) and the course assignments (toolkit.assignments). setup.cfg installs
cl/, scenes/ and tutorials/assignments/ as these data packages; in a source checkout whose
package is not installed that way (an editable install, the tests), the folders are read in place.
What the toolkit writes for later runs (the device probe's verdicts, the OpenCL vendors folder)
goes to the per-user cache folder, `user_cache_folder()`."""
from importlib import resources
from pathlib import Path

import platformdirs

APP_NAME = "simd-light-transport-toolkit"

CHECKOUT = Path(__file__).resolve().parents[2]   # toolkit/core/package_data.py -> the checkout


def data_dir(package, checkout_folder, marker):
    """The folder of data package `package` if it is installed and holds `marker` (a file name
    relative to it), else `checkout_folder` of the source checkout."""
    try:
        installed = Path(str(resources.files(package)))
        if (installed / marker).is_file():
            return installed
    except (ModuleNotFoundError, TypeError):
        pass
    return CHECKOUT / checkout_folder


def user_cache_folder():
    """The per-user cache folder of the toolkit, as the system names it (platformdirs): on Linux
    $XDG_CACHE_HOME/simd-light-transport-toolkit, by default ~/.cache/simd-light-transport-toolkit.
    Read at each call, so that a changed XDG_CACHE_HOME (the tests set it) counts."""
    return platformdirs.user_cache_path(APP_NAME, appauthor=False)

"""Where the files installed beside the code live: the OpenCL sources (toolkit.cl), the bundled
scenes (toolkit.scenes) and the course assignments (toolkit.assignments). setup.cfg installs
cl/, scenes/ and tutorials/assignments/ as these data packages; in a source checkout whose
package is not installed that way (an editable install, the tests), the folders are read in place."""
from importlib import resources
from pathlib import Path

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

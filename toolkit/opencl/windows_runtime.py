"""Intel's CPU runtime from pip, made visible to the OpenCL loader on Windows.

pyopencl's Windows wheel brings the Khronos ICD loader (OpenCL.dll). The loader finds the GPU
drivers through the registry, where their installers write; pip writes no registry key. The
loader also reads `OCL_ICD_FILENAMES` (libraries to load besides, `;`-separated), which is how
a runtime from pip is added for this process only. Intel's library (intelocl64.dll) loads its
own DLLs (libmmd.dll, svml_dispmd.dll, tbb12.dll: intel-cmplr-lib-rt and tbb) from the same
Library\\bin folder, which Windows searches only when told: it goes on PATH and, for loaders that
use the safe search order, in os.add_dll_directory.
"""
import os

from toolkit.opencl.session import session


def register(library, environ=None, add_dll_directory=None):
    """Add `library` to the loader's list (OCL_ICD_FILENAMES) and its folder to the DLL search.
    Returns `library`, or None when the user's own OCL_ICD_FILENAMES is kept."""
    environ = os.environ if environ is None else environ
    add_dll_directory = add_dll_directory or getattr(os, "add_dll_directory", None)
    if environ.get("OCL_ICD_FILENAMES"):
        return None
    folder = str(library.parent)
    environ["OCL_ICD_FILENAMES"] = str(library)
    environ["PATH"] = os.pathsep.join(p for p in (folder, environ.get("PATH")) if p)
    if add_dll_directory is not None:
        # Its handle is kept in the Session: the folder stays searched while the handle lives.
        session().dll_directories.append(add_dll_directory(folder))
    return library

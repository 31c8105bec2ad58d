"""Make the OpenCL implementations that pip installed visible, beside the system's drivers, and
put in the environment what pyopencl and PoCL read from it: the only module, with
windows_runtime.py, that writes the process's environment (the toolkit's settings are read in
toolkit/core/config.py).

When. `prepare()` does it once per process, when a device is first asked for: list_devices
(toolkit/opencl/device.py) calls it before pyopencl's first platform query. Importing the
toolkit registers nothing. That is early enough because the ICD loader reads OCL_ICD_VENDORS at
the first clGetPlatformIDs, not when pyopencl is imported (measured with pyopencl 2026.1.4's
bundled loader: set after `import pyopencl` and before the first get_platforms, Intel's runtime is
found; set after that first query, it is not), and PoCL reads POCL_CACHE_DIR then too (with an
unwritable cache folder, POCL_CACHE_DIR set after the import and before that query gives PoCL's
device back). One variable must come before pyopencl's import: PYOPENCL_NO_CACHE, which pyopencl
reads when it is imported and which decides whether the import opens pytools' cache folder at
all (before_pyopencl_import(), which toolkit/__init__.py calls before it imports anything that
imports pyopencl).

Only where pip installed one (setup.cfg): on Linux x86-64 and on x86-64 Windows. On macOS
pyopencl's wheel uses Apple's OpenCL (its CPU and GPU devices), and a GPU driver registers itself
where its installer put it (/etc/OpenCL/vendors, the Windows registry): nothing to do for those.
On Windows, Intel's runtime is added through OCL_ICD_FILENAMES (toolkit/opencl/windows_runtime.py).
The rest of this text is about Linux.

pyopencl's bundled ICD loader finds PoCL (`pocl-binary-distribution`) by itself, and the
system's drivers through /etc/OpenCL/vendors. Intel's CPU runtime (`intel-opencl-rt`) ships an
`.icd` file that names a placeholder path, so no loader finds it. This module writes a vendors
folder that lists the system's `.icd` files plus one for Intel's library, and points the loader
at it (`OCL_ICD_VENDORS`).

Why Intel's runtime at all: PoCL 3.0 (the newest on the package index) compiles with LLVM 14,
which does not know the newest CPUs (AMD Zen 5) and then builds no kernel. Intel's runtime
builds on any x86-64 CPU; the device picker (toolkit/opencl/device.py) uses it only where PoCL fails.

Set `OCL_ICD_VENDORS` yourself to take full control: the toolkit then registers nothing.

The folder decides which libraries the loader runs, and its name is easy to guess, so it is
kept where only this user can write (the cache folder, else a 0700 folder of the user's own in
the temporary folder) and a folder found there is checked first: another user's, one that others
can write, a symbolic link or one with other files is refused, and then nothing is registered;
`python -m toolkit devices` says why (`vendors_refused`).

Intel's runtime can vectorize a kernel across work-items (SIMD lanes: 8 of them in one AVX2
register, 16 with AVX-512). Measured on a 2-core AMD EPYC, quiet machine, cornell_box 128x128,
with the vectorizer on for every kernel: pt_naive 386k samples/s against 1.89M scalar,
bdpt_parallel_connect 86k against 313k; the vectorized code also gave wrong, run-to-run varying
images then (issue 17), not seen today (issue 22). So the toolkit keeps lanes off unless asked,
per build and not through CL_CONFIG_USE_VECTORIZER, which the runtime reads once for the whole
process: see toolkit/opencl/lanes.py.
"""
import hashlib
import os
import platform
import shutil
import stat
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from types import MappingProxyType

import platformdirs

from toolkit.core.config import config
from toolkit.core.package_data import APP_NAME, user_cache_folder
from toolkit.core.private_folder import UnsafeFolder, private_folder, unsafe_reason, user_tag
from toolkit.opencl import windows_runtime
from toolkit.opencl.session import session

SYSTEM_VENDORS = Path("/etc/OpenCL/vendors")


# The library of Intel's CPU runtime in its pip wheel, per system (its wheels: setup.cfg); read-only.
INTEL_CPU_LIBRARY = MappingProxyType({"Linux": "libintelocl.so", "Windows": "intelocl64.dll"})


def intel_cpu_library():
    """Path of the pip-installed Intel CPU OpenCL library, or None."""
    name = INTEL_CPU_LIBRARY.get(platform.system())
    try:
        files = metadata.distribution("intel-opencl-rt").files or []
    except metadata.PackageNotFoundError:
        return None
    for file in files:
        if file.name == name:
            path = Path(file.locate()).resolve()
            if path.is_file():
                return path
    return None


def vendors_key(icd_lines):
    """The vendors folder's name part: a hash of the `.icd` lines it holds."""
    return hashlib.sha256("\n".join(sorted(icd_lines.values())).encode()).hexdigest()[:16]


def vendor_roots():
    """Where the vendors folder may live, in order: the user's cache folder, else (a read-only
    home) a folder of this user's own in the temporary folder."""
    return [user_cache_folder(), Path(tempfile.gettempdir()) / f"{APP_NAME}-{os.getuid()}"]


def vendors_folder(icd_lines, roots, refused):
    """A folder of `.icd` files (one per library), written once per distinct content, in the
    first of `roots` that this user alone can write; None if there is none. Why each root was
    passed over is appended to `refused`.

    Anyone can compute the folder's name, so it is used only if it is this user's own and nobody
    else can write to it or to the root above it (toolkit/core/private_folder.py), and only if
    it holds exactly the `.icd` files expected: a planted folder is refused, never loaded."""
    folder_name = f"opencl-vendors-{vendors_key(icd_lines)}"
    for root in roots:
        folder = Path(root) / folder_name
        try:
            private_folder(root)
            if not os.path.lexists(folder):
                staging = Path(tempfile.mkdtemp(prefix="vendors-", dir=root))   # made 0700
                for name, line in icd_lines.items():
                    (staging / name).write_text(line + "\n")
                try:
                    staging.rename(folder)  # atomic: a parallel process sees all files or none
                except OSError:
                    shutil.rmtree(staging, ignore_errors=True)
                    if not os.path.lexists(folder):
                        raise
            problem = unsafe_reason(folder) or _unexpected_contents(folder, icd_lines)
            if problem:
                raise UnsafeFolder(f"{folder} is not used: {problem}")
            return folder
        except UnsafeFolder as error:
            refused.append(str(error))
        except OSError as error:   # a read-only home: try the temporary folder
            refused.append(f"{root}: cannot write there ({error.strerror or error})")
    return None


def _unexpected_contents(folder, icd_lines):
    """What is wrong with the files of a vendors folder, or None when it holds exactly the
    `.icd` files expected, each a regular file of this user's own."""
    try:
        names = sorted(os.listdir(folder))
        if names != sorted(icd_lines):
            return f"it holds {', '.join(names) or 'no file'}, not the expected {', '.join(sorted(icd_lines))}"
        for name, line in icd_lines.items():
            info = os.lstat(folder / name)
            if not stat.S_ISREG(info.st_mode) or info.st_uid != os.getuid() or info.st_mode & 0o022:
                return f"{name} is not a regular file of this user's own that only they can write"
            if (folder / name).read_text().strip() != line:
                return f"{name} names another library than expected"
    except (OSError, UnicodeDecodeError) as error:
        return f"cannot read it: {error}"
    return None


def pip_icd_lines():
    """{file name: library} of the vendors folder: the system's drivers plus pip's Intel CPU
    runtime; None without that runtime (then there is nothing to register)."""
    library = intel_cpu_library()
    if library is None:
        return None
    icd_lines = {}
    if SYSTEM_VENDORS.is_dir():  # OCL_ICD_VENDORS replaces this folder, so keep its drivers
        for icd in sorted(SYSTEM_VENDORS.glob("*.icd")):
            try:
                icd_lines[icd.name] = icd.read_text().strip()
            except OSError:
                continue
    icd_lines["toolkit-intel-cpu.icd"] = str(library)
    return icd_lines


def register_pip_runtimes(refused=None):
    """Make pip's Intel CPU runtime visible to the loader, on the systems where pip installs it.

    Returns what was registered (on Linux the vendors folder, on Windows the OCL_ICD_FILENAMES
    setting), or None when nothing was: no Intel runtime (macOS, ARM Linux: none from pip), the
    user's own `OCL_ICD_VENDORS` / `OCL_ICD_FILENAMES`, `TOOLKIT_NO_PIP_RUNTIMES=1`, or (Linux) no
    folder that only this user can write: why is then appended to the list `refused`."""
    refused = [] if refused is None else refused
    if config().no_pip_runtimes:
        return None
    if platform.system() == "Windows":
        library = intel_cpu_library()
        return windows_runtime.register(library) if library else None
    if platform.system() != "Linux" or os.environ.get("OCL_ICD_VENDORS"):
        return None
    icd_lines = pip_icd_lines()
    if icd_lines is None:
        return None
    folder = vendors_folder(icd_lines, vendor_roots(), refused)
    if folder is not None:
        os.environ["OCL_ICD_VENDORS"] = str(folder)
    return folder


def registration_variable():
    """The loader's variable through which pip's runtime is registered on this system."""
    return "OCL_ICD_FILENAMES" if platform.system() == "Windows" else "OCL_ICD_VENDORS"


def users_own_vendors():
    """The user's own OCL_ICD_VENDORS, which the toolkit keeps (then it registers nothing), or None."""
    return os.environ.get("OCL_ICD_VENDORS") or None


# ---- the kernel caches: what pyopencl and PoCL are told ---------------------------------------

def before_pyopencl_import():
    """Where pytools' cache folder cannot be written, pyopencl's import fails to open its cache of
    launch code, and it makes no kernel: then PYOPENCL_NO_CACHE=1 (no pyopencl cache at all).
    Returns why, or None. Once per process (toolkit/opencl/session.py): pyopencl reads the
    variable once, when it is imported; too late after that, and nothing is changed then."""
    return session().once("before_pyopencl_import", _no_pyopencl_cache_if_unwritable)


def _no_pyopencl_cache_if_unwritable():
    if "pyopencl" in sys.modules or os.environ.get("PYOPENCL_NO_CACHE"):
        return None
    problem = unwritable(platformdirs.user_cache_dir("pytools", "pytools"))
    if problem:
        os.environ["PYOPENCL_NO_CACHE"] = "1"
    return problem


def unwritable(folder):
    """Why `folder` cannot be made or written (tried with a file removed at once), or None."""
    try:
        Path(folder).mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".toolkit-", suffix=".probe"):
            pass
    except OSError as error:
        return f"cannot write to {folder}: {error.strerror or error}"
    return None


def _private_pocl_cache():
    """PoCL's default cache folder ($XDG_CACHE_HOME/pocl, else ~/.cache/pocl): where it cannot
    be written, PoCL offers no device at all. Then POCL_CACHE_DIR names a folder of this user's
    own in the temporary folder, made 0700: PoCL loads the compiled kernels it finds there, so
    nobody else may write to it. Returns what was done, or None."""
    if os.environ.get("POCL_CACHE_DIR"):
        return None
    home = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    problem = unwritable(os.path.join(home, "pocl"))
    if not problem:
        return None
    root = Path(tempfile.gettempdir()) / f"{APP_NAME}-{user_tag()}"
    try:
        os.environ["POCL_CACHE_DIR"] = str(private_folder(private_folder(root) / "pocl-cache"))
    except OSError as error:     # UnsafeFolder among them: then PoCL keeps its default
        return f"PoCL's kernel cache: {problem}, and the temporary folder is not usable either ({error})"
    return f"PoCL's kernel cache is in {os.environ['POCL_CACHE_DIR']}: {problem}"


@contextmanager
def compiler_output_shown():
    """Within: pyopencl hands a build's log over as a CompilerWarning with the log itself (the
    only way it hands over the log it stored with a cached binary), instead of a hint to set
    PYOPENCL_COMPILER_OUTPUT=1. toolkit/opencl/program.py builds within it."""
    saved = os.environ.get("PYOPENCL_COMPILER_OUTPUT")
    os.environ["PYOPENCL_COMPILER_OUTPUT"] = "1"
    try:
        yield
    finally:
        if saved is None:
            del os.environ["PYOPENCL_COMPILER_OUTPUT"]
        else:
            os.environ["PYOPENCL_COMPILER_OUTPUT"] = saved


# ---- once per process, before the first platform query -----------------------------------------

@dataclass
class Preparation:
    """What prepare() did: `python -m toolkit devices` and the kernel cache's warnings say it."""
    registered: object = None          # the vendors folder (Linux) or library (Windows) registered, or None
    refused: list = field(default_factory=list)   # why a vendors folder was passed over
    users_vendors: str = None          # the user's own OCL_ICD_VENDORS, kept
    no_pyopencl_cache: str = None      # why pyopencl caches nothing (PYOPENCL_NO_CACHE), or None
    pocl_cache_moved: str = None       # why PoCL's cache was moved to a private temporary folder, or None


def prepare():
    """Register pip's runtimes and give PoCL a cache folder it can write; pyopencl's cache
    failures made non-fatal (pyopencl reads PYOPENCL_CACHE_FAILURE_FATAL when its cache fails,
    and an unset one is a KeyError there). Returns the Preparation. Once per process
    (toolkit/opencl/session.py): the loader reads the environment once, at the first platform query."""
    return session().once("prepare", _prepare_now)


def _prepare_now():
    os.environ.setdefault("PYOPENCL_CACHE_FAILURE_FATAL", "")
    done = Preparation(users_vendors=users_own_vendors(), no_pyopencl_cache=before_pyopencl_import(),
                       pocl_cache_moved=_private_pocl_cache())
    done.registered = register_pip_runtimes(done.refused)
    return done

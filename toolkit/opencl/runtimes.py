"""Make the OpenCL implementations that pip installed visible, beside the system's drivers.

pyopencl's bundled ICD loader finds PoCL (`pocl-binary-distribution`) by itself, and the
system's drivers through /etc/OpenCL/vendors. Intel's CPU runtime (`intel-opencl-rt`) ships an
`.icd` file that names a placeholder path, so no loader finds it. This module writes a vendors
folder that lists the system's `.icd` files plus one for Intel's library, and points the loader
at it (`OCL_ICD_VENDORS`). It must run before the first OpenCL call of the process, which is
why `toolkit/__init__.py` imports it first.

Why Intel's runtime at all: PoCL 3.0 (the newest on the package index) compiles with LLVM 14,
which does not know the newest CPUs (AMD Zen 5) and then builds no kernel. Intel's runtime
builds on any x86-64 CPU; the device picker (toolkit/opencl/device.py) uses it only where PoCL fails.

Set `OCL_ICD_VENDORS` yourself to take full control: the toolkit then registers nothing.

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
import tempfile
from importlib import metadata
from pathlib import Path

from toolkit.core.package_data import APP_NAME, user_cache_folder

SYSTEM_VENDORS = Path("/etc/OpenCL/vendors")


def intel_cpu_library():
    """Path of the pip-installed Intel CPU OpenCL library, or None."""
    try:
        files = metadata.distribution("intel-opencl-rt").files or []
    except metadata.PackageNotFoundError:
        return None
    for file in files:
        if file.name == "libintelocl.so":
            path = Path(file.locate()).resolve()
            if path.is_file():
                return path
    return None


def _vendors_folder(icd_lines):
    """A folder of `.icd` files (one per library), written once per distinct content."""
    key = hashlib.sha256("\n".join(sorted(icd_lines.values())).encode()).hexdigest()[:16]
    for root in (user_cache_folder(), Path(tempfile.gettempdir()) / f"{APP_NAME}-{os.getuid()}"):
        folder = root / f"opencl-vendors-{key}"
        try:
            if not folder.is_dir():
                staging = Path(tempfile.mkdtemp(prefix="vendors-", dir=_mkdir(root)))
                for name, line in icd_lines.items():
                    (staging / name).write_text(line + "\n")
                try:
                    staging.rename(folder)  # atomic: a parallel process sees all files or none
                except OSError:
                    if not folder.is_dir():
                        raise
            return folder
        except OSError:
            continue  # read-only home: try the temporary folder
    return None


def _mkdir(path):
    path.mkdir(parents=True, exist_ok=True)
    return path


def register_pip_runtimes():
    """Point the ICD loader at the system's drivers plus pip's Intel CPU runtime.

    Returns the vendors folder used, or None when nothing was registered (no Intel runtime,
    `OCL_ICD_VENDORS` already set, or `TOOLKIT_NO_PIP_RUNTIMES=1`)."""
    if os.environ.get("OCL_ICD_VENDORS") or os.environ.get("TOOLKIT_NO_PIP_RUNTIMES") == "1":
        return None
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
    folder = _vendors_folder(icd_lines)
    if folder is not None:
        os.environ["OCL_ICD_VENDORS"] = str(folder)
    return folder


registered_vendors = register_pip_runtimes()

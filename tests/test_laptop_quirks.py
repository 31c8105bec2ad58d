"""What differs on a learner's laptop, handled by the device model rather than by luck (issue 37):
a kernel's own work-group limit (Apple's CPU device), kernel sources with Windows line endings,
Windows' folders (no user ids) and its OpenCL loader (OCL_ICD_FILENAMES), and a system without
POSIX resource limits, where only the grader stops, saying why."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyopencl as cl
import pytest

from toolkit.core import private_folder
from toolkit.grading import limits
from toolkit.opencl import device, program, runtimes, windows_runtime
from toolkit.opencl.session import session

ROOT = Path(__file__).resolve().parent.parent


# ---- a kernel's own work-group limit ----------------------------------------------------------

def test_a_kernel_limited_below_the_local_size_is_named_with_its_limit():
    with pytest.raises(program.WorkGroupTooLarge) as info:
        program.check_work_group("pt_naive_extend", 64, 32, "Intel(R) Core(TM) i7-1068NG7 CPU @ 2.30GHz")
    message = str(info.value)
    assert "Intel(R) Core(TM) i7-1068NG7" in message and "pt_naive_extend" in message
    assert "at most 32 work-items" in message and "CL_KERNEL_WORK_GROUP_SIZE" in message
    program.check_work_group("pt_naive_extend", 64, 64, "any device")     # at the limit: runs


def test_a_device_whose_kernels_take_smaller_work_groups_fails_the_probe_saying_so(monkeypatch, queue):
    """Apple's CPU device gives some kernels (barriers, local memory) fewer work-items than the
    device's maximum: the probe asks the kernel, and the device is skipped with that reason."""
    # launch checks a kernel when it first binds it: the probe's queue starts with none bound
    monkeypatch.setattr(device.queue_for_device(queue.device).builds, "launched", {})
    monkeypatch.setattr(program, "_work_group_limit", lambda kernel, d: 16)
    usable, reason, lasting = device._run_probe(queue.device)
    assert not usable and lasting
    assert "runs kernel probe in work-groups of at most 16 work-items" in reason
    assert queue.device.name.strip() in reason


# ---- line endings -------------------------------------------------------------------------------

KERNEL = ('#include "twice.h"\n'
          "__kernel __attribute__((reqd_work_group_size(LOCAL_SIZE, 1, 1)))\n"
          "void twice_all(__global float *x, int n)\n"
          "{\n"
          "    int i = get_global_id(0);\n"
          "    if (i >= n) return;    // the launch is padded to whole work-groups\n"
          "    x[i] = twice(x[i]);\n"
          "}\n")
HEADER = "static inline float twice(float v)\n{\n    return 2.0f * v;   // a header of our own\n}\n"


def test_kernel_sources_with_windows_line_endings_build_the_same_program(tmp_path, queue):
    """A checkout on Windows (git's autocrlf) has CRLF line endings: the expanded source, its line
    numbers and so the build cache key are those of the LF files."""
    for folder, newline in (("lf", "\n"), ("crlf", "\r\n")):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "twice.cl").write_bytes(KERNEL.replace("\n", newline).encode())
        (tmp_path / folder / "twice.h").write_bytes(HEADER.replace("\n", newline).encode())
    lf, crlf = (program.expand_includes("twice.cl", tmp_path / f) for f in ("lf", "crlf"))
    assert crlf == lf and "\r" not in crlf
    built = program.build(queue, "twice.cl", directory=tmp_path / "crlf")
    values = np.arange(4, dtype=np.float32)
    buffer = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR, hostbuf=values)
    program.launch(queue, program.kernel(built, "twice_all"), 4, buffer, np.int32(4))
    cl.enqueue_copy(queue, values, buffer)
    assert values.tolist() == [0.0, 2.0, 4.0, 6.0]


# ---- Windows -----------------------------------------------------------------------------------

def test_without_user_ids_a_users_own_folder_is_trusted(tmp_path, monkeypatch):
    """Windows has no os.getuid: its per-user folders are private by their access lists."""
    monkeypatch.delattr(os, "getuid")
    monkeypatch.setenv("USERNAME", "learner")
    assert private_folder.user_id() is None and private_folder.user_tag() == "learner"
    assert private_folder.private_folder(tmp_path / "cache") == tmp_path / "cache"
    assert private_folder.unsafe_reason(tmp_path / "cache") is None
    (tmp_path / "file").write_text("")
    assert private_folder.unsafe_reason(tmp_path / "file") == "it is not a folder"


def test_on_windows_intels_runtime_is_given_to_the_loader_by_ocl_icd_filenames(tmp_path):
    library = tmp_path / "Library" / "bin" / "intelocl64.dll"
    environ, added = {"PATH": r"C:\Windows"}, []
    assert windows_runtime.register(library, environ, added.append) == library
    assert environ["OCL_ICD_FILENAMES"] == str(library)
    assert environ["PATH"].split(os.pathsep)[0] == str(library.parent)     # its libmmd.dll, tbb12.dll
    assert added == [str(library.parent)]
    own = {"OCL_ICD_FILENAMES": r"C:\mine\opencl.dll"}                     # the user's own setting stays
    assert windows_runtime.register(library, own, added.append) is None and own["OCL_ICD_FILENAMES"].endswith("opencl.dll")


@pytest.mark.parametrize("system, library, registered", [
    ("Windows", "intelocl64.dll", True), ("Darwin", None, False), ("Linux", None, False)])
def test_pip_runtimes_are_registered_only_where_pip_installed_one(monkeypatch, tmp_path, system, library,
                                                                   registered):
    """macOS (Apple's OpenCL) and ARM Linux (no runtime from pip) register nothing."""
    monkeypatch.setattr(runtimes.platform, "system", lambda: system)
    monkeypatch.setattr(runtimes, "intel_cpu_library", lambda: tmp_path / library if library else None)
    monkeypatch.setattr(session(), "dll_directories", [])
    for variable in ("OCL_ICD_FILENAMES", "OCL_ICD_VENDORS", "TOOLKIT_NO_PIP_RUNTIMES"):
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.setenv("PATH", os.environ["PATH"])         # restored after the test
    monkeypatch.setattr(os, "add_dll_directory", lambda folder: folder, raising=False)
    assert (runtimes.register_pip_runtimes() is not None) == registered
    assert ("OCL_ICD_FILENAMES" in os.environ) == registered


def test_without_posix_limits_the_toolkit_runs_and_only_the_grader_refuses(tmp_path):
    """Windows has no `resource` module: the command line still imports, renders are unaffected,
    and `grade` stops with one line that says why (exit 2)."""
    script = ("import sys; sys.modules['resource'] = None\n"
              "from toolkit.cli import main\n"
              f"raise SystemExit(main(['grade', 'compaction', '--kernel', {str(tmp_path / 'mine.cl')!r}]))\n")
    (tmp_path / "mine.cl").write_text("")
    run = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 2, run.stderr
    assert "POSIX resource limits" in run.stderr and "Traceback" not in run.stderr
    with pytest.raises(OSError, match="grade on Linux or macOS"):
        saved, limits.resource = limits.resource, None
        try:
            limits.require_limits()
        finally:
            limits.resource = saved

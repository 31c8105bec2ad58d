"""The runtime set-up on a shared machine (issue 24): the vendors folder another user planted is
refused, the probe's verdicts are kept only where they hold (this CPU, a finished probe, a
well-formed file), and a stale or unwritable kernel cache costs the cache, not the command."""
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pyopencl as cl
import pytest

from toolkit.cli.devices import devices_report
from toolkit.opencl import device, kernel_cache, probe_cache, runtimes
from toolkit.opencl.device_model import is_gpu
from toolkit.opencl.program import build
from toolkit.opencl.session import session

ROOT = Path(__file__).resolve().parent.parent
NOBODY = 65534
ICD = {"vendor.icd": "/usr/lib/libvendor.so"}


def _planted(root, lines, mode=0o755):
    """A vendors folder made by someone else, named as the toolkit would name it."""
    os.makedirs(root, mode=0o700, exist_ok=True)
    folder = root / f"opencl-vendors-{runtimes.vendors_key(ICD)}"
    folder.mkdir()
    for name, line in lines.items():
        (folder / name).write_text(line + "\n")
    folder.chmod(mode)
    return folder


def _refused(root):
    refused = []
    assert runtimes.vendors_folder(ICD, [root], refused) is None
    assert len(refused) == 1
    return refused[0]


def test_the_vendors_folder_is_made_private(tmp_path):
    refused = []
    folder = runtimes.vendors_folder(ICD, [tmp_path / "root"], refused)
    assert refused == [] and folder is not None
    assert (folder / "vendor.icd").read_text().strip() == ICD["vendor.icd"]
    assert (tmp_path / "root").stat().st_mode & 0o777 == 0o700 and folder.stat().st_mode & 0o777 == 0o700
    assert runtimes.vendors_folder(ICD, [tmp_path / "root"], refused) == folder   # found again: used


def test_a_planted_vendors_folder_is_refused(tmp_path):
    """Writable by others, a symbolic link, another library, or (as root) another user's: never used."""
    _planted(tmp_path / "a", ICD, mode=0o777)
    assert "others can write to it" in _refused(tmp_path / "a")
    _planted(tmp_path / "b", {"vendor.icd": "/tmp/evil.so"})
    assert "names another library" in _refused(tmp_path / "b")
    elsewhere = _planted(tmp_path / "c", ICD)
    (tmp_path / "d").mkdir(mode=0o700)
    (tmp_path / "d" / elsewhere.name).symlink_to(elsewhere)
    assert "symbolic link" in _refused(tmp_path / "d")
    (tmp_path / "e").mkdir()
    (tmp_path / "e").chmod(0o777)           # the root above it: whoever writes there can swap the folder
    assert "others can write to it" in _refused(tmp_path / "e")
    if os.getuid() == 0:                    # only root can give a folder to another user
        os.chown(_planted(tmp_path / "f", ICD), NOBODY, NOBODY)
        assert f"belongs to user id {NOBODY}" in _refused(tmp_path / "f")


def test_devices_with_an_unwritable_home_and_a_planted_folder(tmp_path):
    """Issue 24's case: the cache folder cannot be written, and the fallback folder in the
    temporary folder was planted. `devices` runs, registers nothing, says why, and says once
    that the kernel cache is not used (it crashed with KeyError 'PYOPENCL_CACHE_FAILURE_FATAL')."""
    lines = runtimes.pip_icd_lines()
    if lines is None:
        pytest.skip("no pip-installed Intel CPU runtime: nothing is registered anyway")
    (tmp_path / "file").write_text("")      # a home whose cache folder cannot be made
    planted = _planted(tmp_path / "tmp" / f"{runtimes.APP_NAME}-{os.getuid()}", {k: "/tmp/evil.so" for k in lines})
    planted.rename(planted.with_name(f"opencl-vendors-{runtimes.vendors_key(lines)}"))
    environment = {k: v for k, v in os.environ.items() if k not in ("OCL_ICD_VENDORS", "PYOPENCL_CTX")}
    environment.update(XDG_CACHE_HOME=str(tmp_path / "file" / "cache"), TMPDIR=str(tmp_path / "tmp"),
                       TOOLKIT_HIDE_PLATFORMS="oclgrind")   # its probe is slow, and says nothing more here
    result = subprocess.run([sys.executable, "-m", "toolkit", "devices"], cwd=ROOT, capture_output=True,
                            text=True, env=environment, timeout=300)
    assert result.returncode == 0 and "Traceback" not in result.stderr, result.stderr
    assert result.stderr.count("kernel cache is not used") == 1, result.stderr
    assert "Intel's CPU runtime from pip is NOT registered" in result.stdout
    assert "opencl-vendors-" in result.stdout and "is not used" in result.stdout
    assert "Intel(R) OpenCL" not in result.stdout


def test_a_stale_lock_builds_without_the_cache_and_says_so(tmp_path, monkeypatch, queue):
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "lock").write_text("")
    assert kernel_cache.cache_problem(cache) is None                      # a lock in use: wait for it
    old = time.time() - 10 * kernel_cache.STALE_LOCK_SECONDS
    os.utime(cache / "lock", (old, old))
    assert "lock file" in kernel_cache.cache_problem(cache)
    monkeypatch.setenv("TOOLKIT_CACHE_DIR", str(cache))
    (tmp_path / "tiny.cl").write_text("__kernel void tiny(__global int *out) { out[0] = 24; }\n")
    with pytest.warns(kernel_cache.KernelCacheWarning, match="lock file .* s old") as said:
        program = build(queue, "tiny.cl", directory=tmp_path)
        build(queue, "tiny.cl", defines={"AGAIN": 1}, directory=tmp_path)
    assert len(said) == 1                                                 # once, not per build
    assert program.tiny.function_name == "tiny"
    assert sorted(p.name for p in cache.iterdir()) == ["lock"]            # nothing cached, lock left alone


@pytest.fixture
def fresh_probes(tmp_path, monkeypatch, queue):
    """The verdict file of the suite's device in an empty cache folder, forgotten in this process."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(session(), "probe_verdicts", {})
    monkeypatch.setattr(session(), "probe_notes", {})
    return device.verdict_file(device._probe_identity(queue.device))


def test_an_opencl_error_while_probing_is_not_kept(fresh_probes, monkeypatch, queue):
    def out_of_resources(*args, **kwargs):
        raise cl.RuntimeError(cl._cl._ErrorRecord("clEnqueueNDRangeKernel", cl.status_code.OUT_OF_RESOURCES,
                                                  "OUT_OF_RESOURCES"))
    with monkeypatch.context() as patch:
        patch.setattr(device, "launch", out_of_resources)
        usable, reason = device.probe(queue.device)
    assert not usable and "OUT_OF_RESOURCES" in reason
    assert not fresh_probes.exists() and "not kept" in device.probe_note(queue.device)
    session().probe_verdicts.clear()       # the next run probes again, and the device is usable
    assert device.probe(queue.device) == (True, "")
    assert json.loads(fresh_probes.read_text())["usable"] is True
    assert str(fresh_probes) in devices_report()    # `devices` names the file


def test_malformed_or_foreign_verdicts_are_probed_again(fresh_probes, queue):
    here = probe_cache.cpu_identity()
    fresh_probes.parent.mkdir(parents=True)
    for verdict in ({"usable": "false", "reason": "", "cpu": here},     # a string: not a verdict
                    {"usable": False, "reason": "error: unknown target CPU", "cpu": "another CPU"},
                    {"usable": False, "cpu": here}, [False, "x"]):
        fresh_probes.write_text(json.dumps(verdict))
        assert probe_cache.read_verdict(fresh_probes) is None, verdict
    fresh_probes.write_text(json.dumps({"usable": False, "reason": "error: x", "cpu": here}))
    assert probe_cache.read_verdict(fresh_probes) == (False, "error: x")
    assert device.probe(queue.device) == (False, "error: x")      # a kept failure: the error names its file
    unusable = device.Candidate(0, 0, queue.device.platform, queue.device, False, "error: x")
    assert str(fresh_probes) in device.explain_no_usable_device([unusable])
    fresh_probes.parent.chmod(0o777)       # a folder others can write: its verdicts are not read
    assert probe_cache.read_verdict(fresh_probes) is None
    fresh_probes.parent.chmod(0o700)


def test_the_verdict_file_depends_on_the_cpu(monkeypatch):
    """PoCL names its device "pthread-AMD EPYC" on a Zen 4 and a Zen 5: the CPU is in the key."""
    here = probe_cache.verdict_file("the same device")
    monkeypatch.setattr(probe_cache, "cpu_identity", lambda: "vendor_id=AuthenticAMD; cpu family=26")
    assert probe_cache.verdict_file("the same device") != here


def _fake(kind, platform):
    return SimpleNamespace(type=kind, platform=SimpleNamespace(name=platform))


def test_oclgrind_is_not_a_gpu(monkeypatch):
    """Oclgrind reports every device type; has_gpu() and bench's "gpu" must not believe it."""
    every = 0xFFFFFFFF
    assert not is_gpu(_fake(every, "Oclgrind"))
    assert not is_gpu(_fake(cl.device_type.GPU, "Oclgrind"))
    assert is_gpu(_fake(cl.device_type.GPU, "NVIDIA CUDA"))
    monkeypatch.setattr(device, "list_devices", lambda: [(0, 0, None, _fake(every, "Oclgrind")),
                                                         (1, 0, None, _fake(cl.device_type.CPU, "PoCL"))])
    assert not device.has_gpu()
    monkeypatch.setattr(device, "list_devices", lambda: [(0, 0, None, _fake(cl.device_type.GPU, "NVIDIA CUDA"))])
    assert device.has_gpu()


def test_importing_the_toolkit_registers_nothing_until_a_device_is_asked_for():
    """`import toolkit` leaves the loader's environment alone (issue 41); the first device asked
    for registers pip's runtime, before the loader's first look, and finds it."""
    if runtimes.pip_icd_lines() is None:
        pytest.skip("no pip-installed Intel CPU runtime: nothing is registered anyway")
    script = ("import os, sys, toolkit\n"
              "print('after import:', os.environ.get('OCL_ICD_VENDORS'), 'pyopencl' in sys.modules)\n"
              "from toolkit.opencl.device import list_devices\n"
              "names = {platform.name for _, _, platform, _ in list_devices()}\n"
              "print('after list_devices:', bool(os.environ.get('OCL_ICD_VENDORS')), 'Intel(R) OpenCL' in names)\n")
    environment = {k: v for k, v in os.environ.items() if k not in ("OCL_ICD_VENDORS", "TOOLKIT_NO_PIP_RUNTIMES")}
    result = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True,
                            env=environment, timeout=300)
    assert result.returncode == 0, result.stderr
    assert "after import: None True" in result.stdout      # pyopencl imported, nothing registered
    assert "after list_devices: True True" in result.stdout


def test_the_cache_switch_comes_before_pyopencl_is_imported():
    """`import toolkit` decides whether pyopencl may keep a cache (runtimes.before_pyopencl_import)
    before anything imports pyopencl, which reads PYOPENCL_NO_CACHE once. It once came after: the
    settings module imported validate.py for InputError, which imports the layouts and pyopencl."""
    code = ("import sys\n"
            "class Watch:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name == 'pyopencl':\n"
            "            sys.meta_path.remove(self)\n"
            "            from toolkit.opencl.session import session\n"
            "            print('switch first' if 'before_pyopencl_import' in session().done else 'pyopencl first')\n"
            "sys.meta_path.insert(0, Watch())\n"
            "import toolkit\n")
    result = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "switch first"

"""The device probe's verdicts on disk, so that each process need not build and run the probe
kernel again (toolkit/opencl/device.py probes; this module keeps what it found).

A verdict is kept only for what the probe can settle for good, and only for the machine it was
found on:
- The file's name is a hash of the device, its driver, the probe's source and this CPU's
  identity (`cpu_identity`). PoCL names its device after the CPU's brand ("pthread-AMD EPYC" on
  a Zen 4 and on a Zen 5 alike) while its compiler may know one and not the other, so a home
  folder shared by lab machines of two CPU generations must not share a verdict.
- A probe that built and ran (usable, or wrong numbers) or whose build failed is kept. An OpenCL
  error while probing (OUT_OF_RESOURCES on a busy machine) says nothing about the device: it is
  not kept, and the next run probes again.
- A file is read strictly: `usable` must be a JSON true or false (`"false"`, a string, would read
  as true in Python), `reason` a string, and `cpu` this CPU's identity; any other file is ignored
  and probed anew.
- The folder must be this user's own (toolkit/core/private_folder.py): a verdict decides which
  device runs, so one planted by another user is not read.
`python -m toolkit devices` names each verdict's file, to delete it to probe again.
"""
import hashlib
import json
import os
import platform
import re
from pathlib import Path

from toolkit.core.package_data import user_cache_folder
from toolkit.core.private_folder import private_folder, unsafe_reason
from toolkit.opencl.session import session


def cpu_identity():
    """This CPU, as exactly as the system tells: vendor, family, model, stepping, name and a hash
    of its feature flags (/proc/cpuinfo), else what Python's platform module knows. Read once
    per process (toolkit/opencl/session.py)."""
    return session().once("cpu_identity", _read_cpu_identity)


def _read_cpu_identity():
    try:
        info = Path("/proc/cpuinfo").read_text(errors="replace").split("\n\n")[0]
    except OSError:
        info = ""
    fields = dict(re.findall(r"^(vendor_id|cpu family|model|model name|stepping|flags|Features|CPU part)"
                             r"\s*:\s*(.*)$", info, re.MULTILINE))
    flags = fields.pop("flags", "") or fields.pop("Features", "")
    if not fields:
        return f"{platform.machine()} {platform.processor()}".strip() or "unknown CPU"
    parts = [f"{key}={value.strip()}" for key, value in sorted(fields.items())]
    return "; ".join(parts + [f"flags={hashlib.sha256(flags.encode()).hexdigest()[:12]}"])


def verdict_file(identity):
    """The file of one device's verdict: `identity` (the device, its driver, the probe's source)
    hashed with this CPU's identity."""
    key = hashlib.sha256(f"{identity}\0{cpu_identity()}".encode()).hexdigest()[:24]
    return user_cache_folder() / "probes" / f"{key}.json"


def read_verdict(file):
    """(usable, reason) from a verdict file, or None: missing, unreadable, malformed, from another
    CPU, or in a folder that is not this user's own."""
    if unsafe_reason(file.parent):
        return None
    try:
        verdict = json.loads(file.read_text())
    except (OSError, ValueError):
        return None
    if not (isinstance(verdict, dict) and isinstance(verdict.get("usable"), bool)
            and isinstance(verdict.get("reason"), str) and verdict.get("cpu") == cpu_identity()):
        return None
    return verdict["usable"], verdict["reason"]


def write_verdict(file, usable, reason, device_name):
    """Keep a verdict (written whole, then renamed into place); None, or why it was not kept."""
    try:
        private_folder(user_cache_folder())
        private_folder(file.parent)
        staging = file.with_suffix(f".{os.getpid()}.tmp")
        try:
            staging.write_text(json.dumps({"usable": bool(usable), "reason": str(reason), "cpu": cpu_identity(),
                                           "device": device_name}))
            staging.replace(file)
        finally:
            if staging.exists():
                staging.unlink()
    except OSError as error:
        return f"not kept: {error}"
    return None

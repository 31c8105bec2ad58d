"""Folders of the toolkit's own that no other user can write: where it keeps what a later run
loads (the OpenCL vendors folder, whose `.icd` files name the libraries the loader runs) or
trusts (the device probe's verdicts).

A lab machine is shared. Whoever can write to such a folder chooses what the toolkit loads, so
a folder the toolkit makes is made 0700, and a folder found already there is used only if it is
a real folder (not a symbolic link, read with os.lstat), belongs to the current user and no one
else can write to it. Otherwise `unsafe_reason` says why, and the caller uses nothing from it.
"""
import os
import stat
from pathlib import Path

from toolkit.core.config import config


class UnsafeFolder(OSError):
    """A folder another user could have written: its contents are not used."""


def user_id():
    """This user's id, or None on Windows: there a folder's access list, not an owner id and mode
    bits, says who may write to it, and the per-user folders (%LOCALAPPDATA%, which platformdirs
    names) are the user's own by default."""
    return os.getuid() if hasattr(os, "getuid") else None


def user_tag():
    """A part of a folder name that differs between the users of one machine."""
    uid = user_id()
    return str(uid) if uid is not None else (config().user_name or "user")


def unsafe_reason(path):
    """Why `path` cannot be trusted (another owner, writable by others, a symbolic link, not a
    folder), or None when it is the current user's own folder and only theirs to write."""
    try:
        info = os.lstat(path)
    except OSError as error:
        return f"cannot read it: {error.strerror or error}"
    if stat.S_ISLNK(info.st_mode):
        return "it is a symbolic link"
    if not stat.S_ISDIR(info.st_mode):
        return "it is not a folder"
    if user_id() is None:        # Windows: no owner id or mode bits to check (see user_id)
        return None
    if info.st_uid != os.getuid():
        return f"it belongs to user id {info.st_uid}, not to this user ({os.getuid()})"
    if info.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        mode = stat.S_IMODE(info.st_mode)
        return f"others can write to it (mode {mode:o}; `chmod go-w` it if its contents are yours)"
    return None


def private_folder(path):
    """`path`, made 0700 if missing (its parents as the system makes them), else checked with
    unsafe_reason. Raises UnsafeFolder naming the folder and the reason, OSError when it cannot
    be made."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.mkdir(path, 0o700)
    except FileExistsError:
        pass
    reason = unsafe_reason(path)
    if reason:
        raise UnsafeFolder(f"{path} is not used: {reason}")
    return path

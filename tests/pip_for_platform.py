"""pip, resolving for another platform than the one it runs on: what `pip install` would install on
a Mac, a Windows laptop or an ARM Linux board (tests/test_platform_install.py).

`pip install --dry-run --platform TAG` picks wheels for TAG, but evaluates the environment
markers of every requirement (`; sys_platform == "win32"`) for the machine pip runs on (pip's
issue 11664). setup.cfg's per-platform dependencies are exactly such markers, so this script
runs pip with the markers of the target platform: it replaces the marker environment of pip's
own `packaging` before pip starts. Run by hand:

    python tests/pip_for_platform.py win_amd64 dist/simd_light_transport_toolkit-0.1.0-py3-none-any.whl
"""
import sys

PYTHON = "3.12"

# The marker variables of each target (PEP 508), and the wheel tags pip may pick for it.
_MAC = {"os_name": "posix", "sys_platform": "darwin", "platform_system": "Darwin"}
_LINUX = {"os_name": "posix", "sys_platform": "linux", "platform_system": "Linux"}
_WINDOWS = {"os_name": "nt", "sys_platform": "win32", "platform_system": "Windows"}
TARGETS = {
    "macosx_14_0_arm64": (dict(_MAC, platform_machine="arm64"), ["macosx_14_0_arm64"]),
    "macosx_13_0_x86_64": (dict(_MAC, platform_machine="x86_64"), ["macosx_13_0_x86_64"]),
    "win_amd64": (dict(_WINDOWS, platform_machine="AMD64"), ["win_amd64"]),
    "manylinux_x86_64": (dict(_LINUX, platform_machine="x86_64"),
                         [f"manylinux{v}_x86_64" for v in ("2014", "_2_28", "_2_34")]),
    "manylinux_aarch64": (dict(_LINUX, platform_machine="aarch64"),
                          [f"manylinux{v}_aarch64" for v in ("2014", "_2_28", "_2_34")]),
}


def marker_environment(target):
    """The full PEP 508 environment of `target` under CPython PYTHON."""
    variables, _ = TARGETS[target]
    return dict(variables, implementation_name="cpython", implementation_version=f"{PYTHON}.0",
                platform_python_implementation="CPython", platform_release="", platform_version="",
                python_version=PYTHON, python_full_version=f"{PYTHON}.0")


def pip_arguments(target, wheel, folder):
    """`pip install --dry-run` of `wheel` for `target`, wheels only, into (nothing in) `folder`."""
    _, tags = TARGETS[target]
    platforms = [arg for tag in tags for arg in ("--platform", tag)]
    return ["install", "--dry-run", "--only-binary=:all:", "--python-version", PYTHON, *platforms,
            "--target", str(folder), "--disable-pip-version-check", "--no-color", str(wheel)]


def main(target, wheel, folder):
    from pip._internal.cli.main import main as pip_main
    from pip._vendor.packaging import markers
    environment = marker_environment(target)
    markers.default_environment = lambda: dict(environment)   # what Marker.evaluate() reads
    return pip_main(pip_arguments(target, wheel, folder))


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4) or sys.argv[1] not in TARGETS:
        print(f"usage: python {sys.argv[0]} {{{','.join(TARGETS)}}} WHEEL [TARGET_FOLDER]", file=sys.stderr)
        raise SystemExit(2)
    import tempfile
    with tempfile.TemporaryDirectory() as scratch:
        raise SystemExit(main(sys.argv[1], sys.argv[2], sys.argv[3] if len(sys.argv) == 4 else scratch))

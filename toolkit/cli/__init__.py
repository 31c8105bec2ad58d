"""Command line: `python -m toolkit {render,devices,...}`. Examples: docs/usage.md."""
import argparse
import sys
import warnings

from toolkit.cli import bench, compare, course, crosscheck, demo, devices, gpucheck, grade, render, study
from toolkit.cli.devices import devices_report
from toolkit.cli.options import DEVICE_HELP
from toolkit.core.scene import SceneError
from toolkit.opencl.session import session
from toolkit.opencl.device import NoOpenCLError
from toolkit.opencl.program import KernelBuildError
from toolkit.grading.stubs import AssignmentNotWritten

__all__ = ["build_parser", "main", "devices_report"]

# The registry: each module adds its command's subparser and sets `run`, the function that runs
# it (toolkit/cli/render.py is the pattern to copy). `--help` lists the commands in this order.
COMMANDS = (render, devices, crosscheck, compare, bench, gpucheck, study, grade, course, demo)


def build_parser():
    """The parser of `python -m toolkit`: the global options and one subcommand per module of
    COMMANDS (the documentation's command-line page is generated from it)."""
    parser = argparse.ArgumentParser(prog="python -m toolkit", description=__doc__)
    parser.add_argument("--device", help=DEVICE_HELP)
    parser.add_argument("--verbose", action="store_true", help="print every kernel build log in full")
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_command(sub)
    return parser


def _warning_line(message, category, filename, lineno, file=None, line=None):
    print(f"warning: {message}", file=sys.stderr)


def main(argv=None):
    """Run one command; bad input (a scene, a value, a file, a kernel that does not build, no
    OpenCL device) is one `error:` line on stderr and exit code 2, never a traceback."""
    args = build_parser().parse_args(argv)
    session().verbose_builds = session().verbose_builds or args.verbose
    shown = warnings.showwarning
    warnings.showwarning = _warning_line      # one "warning: ..." line, not file and source line
    try:
        return args.run(args)
    except (NoOpenCLError, KernelBuildError) as error:
        # A compiler log and the list of devices with their fixes keep their lines.
        print(f"error: {error}", file=sys.stderr)
        return 2
    except (SceneError, ValueError, OSError, AssignmentNotWritten) as error:
        print("error: " + " ".join(str(error).split()), file=sys.stderr)   # bad input: one line
        return 2
    finally:
        warnings.showwarning = shown

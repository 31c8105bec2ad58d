"""Run every technique once on Oclgrind with its data-race detector on, at a size where the
stream is regenerated and compacted, for tests/test_races.py (which reads what Oclgrind
writes to stderr). Run as a script: `python tests/oclgrind_races.py`; it prints one line of
JSON per run on stdout, and a line `=== NAME` on stderr before each, so that the test can
say which run a report belongs to. The first run is the control, a kernel with a known race."""
import inspect
import json
import os
import sys
from pathlib import Path

os.environ["OCLGRIND_DATA_RACES"] = "1"   # read when Oclgrind loads: before the first OpenCL call
ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
import pyopencl as cl  # noqa: E402

import toolkit  # noqa: E402
from toolkit.opencl import program  # noqa: E402
from toolkit.opencl.device import get_queue  # noqa: E402
from toolkit.techniques import TECHNIQUES  # noqa: E402

# 8x8 pixels, 4 spp: 256 samples through a stream (or pool) of 64, so slots are regenerated and
# compacted several times, and a last, partly filled wave drains. The size (issue 22).
RESOLUTION, SPP, IN_FLIGHT = (8, 8), 4, 64
# Runs with the SIMD counters on as well: the BDPT walk's kernel then adds its own lanes to the
# step log (cl/simd_counters.h), with a barrier and atomics of its own; pt_inplace_regen's steps
# write their lanes to turns of one buffer that simd_count_turns reads a round at a time. Named
# "<technique> counted".
COUNTED = ("bdpt_naive_connect", "pt_inplace_regen")


def announce(name):
    print(f"=== {name}", file=sys.stderr, flush=True)


def control(queue):
    """The racy kernel, which Oclgrind must report: proof that the detector is on."""
    built = program.build(queue, "racy.cl", directory=ROOT / "tests" / "fixtures" / "races")
    word = cl.Buffer(queue.context, cl.mem_flags.READ_WRITE, 4 * (program.LOCAL_SIZE + 1))
    program.launch(queue, program.kernel(built, "racy"), program.LOCAL_SIZE, word)
    queue.finish()


def in_flight_options(cls):
    """stream_size / pool_size = IN_FLIGHT for the techniques that take them."""
    names = {n for c in cls.__mro__ if "__init__" in vars(c) for n in inspect.signature(c.__init__).parameters}
    return {name: IN_FLIGHT for name in ("stream_size", "pool_size") if name in names}


def main():
    queue = get_queue("oclgrind")
    announce("control")
    control(queue)
    print(json.dumps({"run": "control", "device": queue.device.platform.name}), flush=True)
    runs = [(name, False) for name in sorted(TECHNIQUES)] + [(name, True) for name in COUNTED]
    for name, count_simd in runs:
        run = f"{name} counted" if count_simd else name
        announce(run)
        options = in_flight_options(TECHNIQUES[name])
        result = toolkit.render(technique=name, spp=SPP, resolution=RESOLUTION, device="oclgrind", options=options,
                                count_simd=count_simd)
        print(json.dumps({"run": run, "device": result.stats["device"], "options": options,
                          "samples_per_pixel": result.stats["samples_per_pixel"],
                          "finite": bool(np.isfinite(result.image).all())}), flush=True)


if __name__ == "__main__":
    main()

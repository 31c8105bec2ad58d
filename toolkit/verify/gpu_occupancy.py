"""How many warps of a kernel an NVIDIA SM can hold at once, from what ptxas reports for it.

A GPU hides the wait for memory by switching between the warps it holds; the more it holds, the
more waits it can hide. What a kernel asks for per thread (registers) and per work-group
(shared memory) limits how many fit. This is the arithmetic of NVIDIA's occupancy calculator
(cuda_occupancy.h, cudaOccMaxBlocksPerSMRegsLimit and friends) for one architecture, sm_90
(Hopper: H100, H200):
- registers are handed to each warp in blocks of 256, from one of the SM's 4 sub-partitions
  (16,384 registers each): a warp of 32 threads using 118 registers takes 3,840, so a
  sub-partition holds 4 such warps and the SM 16;
- shared memory is handed to each work-group in blocks of 128 bytes, with 1 KB more that the
  driver keeps per work-group, from the SM's 228 KB;
- whole work-groups only: a work-group of 64 work-items is 2 warps, and an SM runs at most 32
  work-groups and 64 warps.
"""
from dataclasses import dataclass

SM90 = dict(warp_size=32, registers_per_sm=65_536, register_block=256, sub_partitions=4,
            max_registers_per_thread=255, shared_per_sm=228 * 1024, shared_block=128,
            shared_reserved_per_group=1024, max_warps=64, max_groups=32)


@dataclass
class Occupancy:
    warps: int          # warps of this kernel one SM holds at once (of max_warps)
    max_warps: int
    limited_by: str     # "registers", "shared memory", "warps" or "work-groups"

    @property
    def fraction(self):
        return self.warps / self.max_warps


def _round_up(value, block):
    return -(-value // block) * block


def warps_per_sm(registers, shared_bytes=0, local_size=64, gpu=SM90):
    """Occupancy of a kernel using `registers` per thread and `shared_bytes` of shared (OpenCL
    local) memory per work-group of `local_size` work-items, on `gpu` (default sm_90)."""
    warps_per_group = -(-local_size // gpu["warp_size"])
    limits = {"warps": gpu["max_warps"] // warps_per_group, "work-groups": gpu["max_groups"]}
    if registers > gpu["max_registers_per_thread"]:
        raise ValueError(f"{registers} registers per thread: more than sm_90's {gpu['max_registers_per_thread']}")
    if registers:
        per_warp = _round_up(registers * gpu["warp_size"], gpu["register_block"])
        warps_per_partition = gpu["registers_per_sm"] // gpu["sub_partitions"] // per_warp
        limits["registers"] = warps_per_partition * gpu["sub_partitions"] // warps_per_group
    per_group = _round_up(shared_bytes + gpu["shared_reserved_per_group"], gpu["shared_block"])
    limits["shared memory"] = gpu["shared_per_sm"] // per_group
    # The tightest limit wins; on a tie, the SM's own (a kernel at the SM's maximum is limited by
    # nothing it asks for), then the ones its author can change.
    order = ("warps", "work-groups", "registers", "shared memory")
    limited_by = min(limits, key=lambda kind: (limits[kind], order.index(kind)))
    return Occupancy(limits[limited_by] * warps_per_group, gpu["max_warps"], limited_by)

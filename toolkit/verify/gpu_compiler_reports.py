"""What the GPU compilers say about each kernel they built, read from their own output:
- NVIDIA: `ptxas -v` (registers per thread, stack frame and spills in bytes per thread, shared
  memory per work-group);
- AMD (amdgcn): the assembly clang writes, whose metadata names each kernel's VGPRs and SGPRs
  (vector and scalar registers), spilled registers, scratch (private memory per work-item, the
  stack) and LDS (local memory per work-group), and whose comments give the occupancy the
  compiler computed (waves per SIMD, of 8 on gfx90a).
"""
import re

_ENTRY = re.compile(r"Compiling entry function '(\w+)'")
_PROPERTIES = re.compile(r"Function properties for (\w+)")
_FRAME = re.compile(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads")
_USED = re.compile(r"Used (\d+) registers")
_SHARED = re.compile(r"(\d+) bytes smem")


def ptxas_kernels(log):
    """{kernel: {registers, stack_bytes, spill_bytes, spill_load_bytes, shared_bytes}} from the
    output of `ptxas -v`. Functions that are not kernels (called ones, left un-inlined) have
    "Function properties" of their own; only the kernels' (entry functions') are kept."""
    kernels, entry, properties_of = {}, None, None
    for line in log.splitlines():
        if match := _ENTRY.search(line):
            entry = match.group(1)
            kernels[entry] = {"registers": 0, "stack_bytes": 0, "spill_bytes": 0, "spill_load_bytes": 0,
                              "shared_bytes": 0}
        elif match := _PROPERTIES.search(line):
            properties_of = match.group(1)
        elif (match := _FRAME.search(line)) and properties_of == entry and entry:
            kernels[entry].update(stack_bytes=int(match.group(1)), spill_bytes=int(match.group(2)),
                                  spill_load_bytes=int(match.group(3)))
        elif (match := _USED.search(line)) and entry:
            kernels[entry]["registers"] = int(match.group(1))
            if shared := _SHARED.search(line):
                kernels[entry]["shared_bytes"] = int(shared.group(1))
    return kernels


_PTX_ENTRY = re.compile(r"^\.entry\s+(\w+)\s*\(", re.MULTILINE)
_PTX_TARGET = re.compile(r"^\.target\s+(\w+)", re.MULTILINE)


def ptx_entries(ptx):
    """The kernels (entry functions) of a PTX file, in its order."""
    return _PTX_ENTRY.findall(ptx)


def ptx_target(ptx):
    """The architecture a PTX file was written for (`.target sm_90`), or None."""
    match = _PTX_TARGET.search(ptx)
    return match.group(1) if match else None


# The metadata's fields per kernel that we keep, and our names for them.
_AMD_FIELDS = {"vgpr_count": "vgprs", "sgpr_count": "sgprs", "agpr_count": "agprs",
               "vgpr_spill_count": "vgpr_spills", "sgpr_spill_count": "sgpr_spills",
               "private_segment_fixed_size": "scratch_bytes", "group_segment_fixed_size": "lds_bytes"}
_SIZE = re.compile(r"^\s*\.size\s+(\w+),")
_OCCUPANCY = re.compile(r"^; Occupancy: (\d+)")


def amdgcn_kernels(assembly):
    """{kernel: {vgprs, sgprs, agprs, vgpr_spills, sgpr_spills, scratch_bytes, lds_bytes,
    waves_per_simd}} from clang's amdgcn assembly (-S): the `amdhsa.kernels` metadata, a list
    with one entry ("  - ") per kernel whose fields sit four spaces in ("    .vgpr_count: 157"),
    and the "; Occupancy: N" comment that follows each function's body (after its `.size`)."""
    entries, occupancy, function, in_metadata = [], {}, None, False
    for line in assembly.splitlines():
        if match := _SIZE.match(line):
            function = match.group(1)
        elif (match := _OCCUPANCY.match(line)) and function:
            occupancy[function] = int(match.group(1))
        elif line.startswith("amdhsa.kernels:"):
            in_metadata = True
        elif in_metadata and line and not line.startswith(" "):
            in_metadata = False            # the next top-level key: the list has ended
        elif in_metadata and line.startswith("  - "):
            entries.append({})
            _amd_field(entries[-1], line[4:])
        elif in_metadata and line.startswith("    .") and entries:
            _amd_field(entries[-1], line[4:])
    named = {}
    for entry in entries:
        name = entry.pop("name")
        named[name] = {ours: int(entry.get(theirs, 0)) for theirs, ours in _AMD_FIELDS.items()}
        named[name]["waves_per_simd"] = occupancy.get(name)
    return named


def _amd_field(entry, text):
    """One `.key: value` line of the metadata into `entry` (lists and nested maps are skipped)."""
    key, _, value = text.partition(":")
    if key.startswith(".") and value.strip():
        entry[key[1:]] = value.strip()

"""The OpenCL runtime: finding, probing and picking devices, the device model (vendor, warp width,
work sizes), building and launching programs, the scene on the device, compaction and ray casts.
Imports only toolkit.core."""

#!/usr/bin/env bash
# Issue 50, check 3: an autograder zip's setup.sh in a fresh Debian 12 root, then run_autograder
# grading the reference solution (100), the untouched stub (0) and a kernel that does not build
# (0, the compiler's message) there. Not part of the test suite: it needs root, debootstrap, and
# the network to Debian's mirror and the package index, and takes minutes (results/issue50_gradescope.md).
#
#   sudo tests/gradescope_debootstrap.sh ZIP [ROOTFS]
#
# ZIP: one of `python -m toolkit course export DIR --gradescope`'s zips. ROOTFS: a folder made by
# `debootstrap --variant=minbase bookworm ROOTFS` (made there if it does not exist). Gradescope's
# images are Ubuntu; Debian is what debootstrap makes here. Prints each step's time; the three
# results.json are left in ROOTFS/autograder/results-*.json.
set -euo pipefail
zip="$(realpath "$1")"
rootfs="${2:-/tmp/gradescope-bookworm}"
[ "$(id -u)" = 0 ] || { echo "run as root (debootstrap and chroot)" >&2; exit 2; }
step() { echo "== $1: $2 s"; }

if [ ! -d "$rootfs/usr" ]; then
    start=$SECONDS
    debootstrap --variant=minbase bookworm "$rootfs" http://deb.debian.org/debian >/dev/null
    step "debootstrap bookworm" $((SECONDS - start))
fi
cp /etc/resolv.conf "$rootfs/etc/resolv.conf"
# Behind a proxy that inspects TLS, pip in the root needs this machine's certificates (PIP_CERT).
pass_cert=()
if [ -n "${PIP_CERT:-}" ]; then
    cp "$PIP_CERT" "$rootfs/etc/host-ca-certificates.crt"
    pass_cert=(PIP_CERT=/etc/host-ca-certificates.crt)
fi
mounted=()
for fs in proc sys dev; do
    if ! mountpoint -q "$rootfs/$fs"; then
        mount --rbind "/$fs" "$rootfs/$fs" && mounted+=("$rootfs/$fs")
    fi
done
cleanup() { for m in "${mounted[@]}"; do umount -R "$m" || true; done; }
trap cleanup EXIT

# Gradescope's layout: the zip in /autograder/source, run_autograder copied to /autograder
rm -rf "$rootfs/autograder"
mkdir -p "$rootfs/autograder/source" "$rootfs/autograder/submission" "$rootfs/autograder/results"
(cd "$rootfs/autograder/source" && python3 -c 'import sys, zipfile; zipfile.ZipFile(sys.argv[1]).extractall()' "$zip")
chmod +x "$rootfs/autograder/source/setup.sh" "$rootfs/autograder/source/run_autograder"
cp "$rootfs/autograder/source/run_autograder" "$rootfs/autograder/run_autograder"

start=$SECONDS
chroot "$rootfs" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root "${pass_cert[@]}" bash -c \
    "apt-get update -q >/dev/null && cd /autograder/source && bash ./setup.sh"
step "setup.sh (apt-get update included)" $((SECONDS - start))

# the submissions, from the toolkit installed in the root: its reference solution, the stub, and
# the solution with a line that does not build
prepare='import sys
from toolkit.grading.checks import ASSIGNMENTS
from toolkit.grading.gradescope_run import read_settings
from toolkit.opencl.program import cl_dir
a = ASSIGNMENTS[read_settings("/autograder/source")["assignment"]]
kind, out = sys.argv[1], "/autograder/submission/" + a.replaces
text = (a.folder / a.stub).read_text() if kind == "stub" else (cl_dir() / a.replaces).read_text()
open(out, "w").write(text + ("int this_does_not_build = ;\n" if kind == "broken" else ""))'
for kind in solution stub broken; do
    rm -rf "$rootfs/autograder/submission"/* "$rootfs/autograder/results"/*
    chroot "$rootfs" /usr/bin/env -i /opt/simd-toolkit/bin/python -c "$prepare" "$kind"
    start=$SECONDS
    chroot "$rootfs" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root bash -c \
        "cd /autograder && ./run_autograder > /autograder/results/stdout 2>&1"
    step "run_autograder, $kind" $((SECONDS - start))
    cp "$rootfs/autograder/results/results.json" "$rootfs/autograder/results-$kind.json"
    python3 -c 'import json, sys; r = json.load(open(sys.argv[1])); print(sys.argv[2], "score", r["score"])' \
        "$rootfs/autograder/results-$kind.json" "$kind"
done

"""Freed arrays go back to the operating system once the doctor fixed glibc's mmap threshold
(identification/base/memory.py); each check runs in a process of its own, whose allocator
state no earlier test has shaped."""
from __future__ import annotations

import platform
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="glibc's malloc only")

SCRIPT = r"""
import sys
import numpy as np
from identification.base.memory import return_freed_arrays

def rss_mib():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return float(line.split()[1]) / 1024

if sys.argv[1] == "fixed":
    assert return_freed_arrays()
big = np.ones(16 << 17)          # 16 MiB, mapped; freeing it raises glibc's default threshold
del big
before = rss_mib()
blocks, small = [], []
for i in range(40):              # 4 MiB arrays, each followed by a small array that stays
    blocks.append(np.ones(1 << 19))
    small.append(np.ones(64))
del blocks
print(rss_mib() - before)
"""


def _retained_mib(mode: str) -> float:
    out = subprocess.run([sys.executable, "-c", SCRIPT, mode], capture_output=True, text=True, check=True)
    return float(out.stdout.strip())


def test_freed_arrays_stay_resident_under_the_default_and_go_back_with_the_threshold_fixed():
    """160 MiB of 4 MiB arrays, each followed by a small array that lives on, then freed: under
    glibc's moving threshold they came from the heap and stay resident behind the small ones;
    with return_freed_arrays they were mapped and are returned."""
    assert _retained_mib("default") > 100.0
    assert _retained_mib("fixed") < 10.0

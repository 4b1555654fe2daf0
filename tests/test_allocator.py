"""The command line's allocator settings: a freed large array's memory kept in the heap for the next."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

import dynamics.runtime.allocator as allocator
from dynamics.runtime.allocator import keep_freed_memory

# glibc's own account (mallinfo2) of a 20 MB array while it lives and once freed
ACCOUNT = textwrap.dedent("""
    import ctypes, json, sys
    import numpy as np
    from dynamics.runtime.allocator import keep_freed_memory

    class Info(ctypes.Structure):
        _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                                         "fsmblks", "uordblks", "fordblks", "keepcost")]

    mallinfo2 = ctypes.CDLL(None).mallinfo2
    mallinfo2.restype = Info
    taken = keep_freed_memory() if sys.argv[1] == "kept" else None
    array = np.ones(20 * 2**17)
    alive = mallinfo2()
    del array
    freed = mallinfo2()
    print(json.dumps({"taken": taken, "mapped_alive": alive.hblkhd, "heap_free_after": freed.fordblks}))
""")


def _account(mode: str) -> dict:
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    run = subprocess.run([sys.executable, "-c", ACCOUNT, mode], capture_output=True, text=True, check=True,
                         env={**os.environ, "PYTHONPATH": root})
    return json.loads(run.stdout)


@pytest.mark.skipif(not allocator._glibc(), reason="the thresholds are glibc's (mallopt): elsewhere nothing is set")
def test_a_freed_array_stays_in_the_heap_for_the_next():
    default, kept = _account("default"), _account("kept")
    megabytes = 20 * 2**20
    assert default["mapped_alive"] >= megabytes  # by default its own mmap, unmapped when freed: pages faulted anew
    assert default["heap_free_after"] < megabytes
    assert kept["taken"] is True
    assert kept["mapped_alive"] < 4 * 2**20  # from the heap (the 20 MB array not among the mapped blocks)
    assert kept["heap_free_after"] >= megabytes  # and kept there once freed


def test_off_glibc_nothing_is_set(monkeypatch):
    monkeypatch.setattr(allocator.os, "confstr", lambda name: (_ for _ in ()).throw(ValueError(name)))
    monkeypatch.setattr(allocator.ctypes, "CDLL", lambda *args: pytest.fail("mallopt called off glibc"))
    assert keep_freed_memory() is False

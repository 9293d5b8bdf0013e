"""Opt-in guard against the abort at exit of a process that loaded a pythonfmu 0.7.0 binary.

pythonfmu's C++ wrapper releases its interpreter holder twice when the process ends (PythonFMU
issue 229): the heap is corrupted, and glibc aborts in a later exit handler ("free(): corrupted
unsorted chunks"), after the host has done its work but with exit status 134. With
``SUSPENSION_FMU_QUICK_EXIT=1`` in the environment (tools/fmu-env exports it), the first FMU
loaded in a Linux process registers two C exit handlers, which run before those registered
earlier (the wrapper's among them): ``fcloseall`` flushes and closes every stdio stream, then
``_exit`` ends the process with the status the host gave ``exit``. Handlers the host registered
before it instantiated the FMU (C++ static destructors, atexit functions) are skipped: a host
that relies on them must leave this off. Only libc functions are registered (no Python callback,
which could outlive the interpreter). Measured in docs/masters.md.
"""
from __future__ import annotations

import ctypes
import os
import sys

ENV = "SUSPENSION_FMU_QUICK_EXIT"


def install() -> bool:
    """Register the handlers once per process if ``ENV`` is "1" on Linux; True if they are registered."""
    if os.environ.get(ENV) != "1" or not sys.platform.startswith("linux"):
        return False
    if getattr(sys, "_suspension_fmu_quick_exit", False):
        return True
    try:  # never into the host: a failure leaves the process as it was
        libc = ctypes.CDLL(None)
        # exit() runs its handlers last-registered first: fcloseall, then _exit(status). on_exit
        # (glibc) calls its handler with the exit status as first argument, _exit's only one;
        # __cxa_atexit (what atexit() is made of) calls fcloseall with an argument it ignores.
        if libc.on_exit(ctypes.cast(libc._exit, ctypes.c_void_p), None) != 0:
            return False
        libc.__cxa_atexit(ctypes.cast(libc.fcloseall, ctypes.c_void_p), None, None)
    except (OSError, AttributeError):
        return False
    sys._suspension_fmu_quick_exit = True
    return True

"""FMI 2 callbacks for tests that drive an FMU through FMPy's FMU2Slave/FMU2Model directly.

FMPy's default callbacks (`instantiate()` with no callbacks) log through a native proxy that
keeps ONE logger in a static variable (fmpy/logging: s_logger), re-pointed by every
simulate_fmu(..., logger=...) to a ctypes callback that is freed when that call returns. An FMU
that logs through the default callbacks after such a call jumps into freed memory: a
segmentation fault that depends on the tests' order (seen on a fresh clone). These callbacks
call Python directly: dampnet's FMUs always log as logger(env, name, status, category, "%s",
message), and on x86-64 Linux (the only platform the FMUs are built for) the variadic message
arrives like a sixth fixed argument."""

from __future__ import annotations

from ctypes import CFUNCTYPE, c_char_p, c_int, c_void_p, cast

from fmpy import calloc, free
from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                        fmi2CallbackLoggerTYPE)

_Logger = CFUNCTYPE(None, c_void_p, c_char_p, c_int, c_char_p, c_char_p, c_char_p)


def callbacks(messages: list[str] | None = None) -> fmi2CallbackFunctions:
    """Callbacks whose logger appends each message to `messages`; keep the returned object
    alive until the instance is freed (the FMU keeps pointers into it)."""
    def log(_env, _name, _status, _category, fmt, arg):
        if messages is not None:
            messages.append((arg if fmt == b"%s" else fmt).decode(errors="replace"))

    cb = fmi2CallbackFunctions()
    cb._logger = _Logger(log)  # the ctypes function object lives as long as the struct
    cb.logger = cast(cb._logger, fmi2CallbackLoggerTYPE)
    cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    return cb

"""One process-wide FMI 2 logger behind fmpy's message-formatting proxy.

fmpy formats an FMU's variadic log message in a small native library (`fmpy.logging`) that keeps
ONE static pointer to the Python logger it forwards to; every `addLoggerProxy` call overwrites it,
and fmpy's own default callbacks forward through the same pointer. A logger made per run and then
freed left that pointer dangling: the next FMU to log through fmpy's defaults (in the same
process) jumped into freed memory — a segfault in `fmi2Instantiate` of a foreign-GUID FMU
(tests/test_fmu.py::test_instantiate_rejects_a_foreign_guid).

So the proxy points at `_dispatch`, which lives as long as the process, and is pointed there again
before every instantiation (other code, fmpy's own simulate_fmu included, re-points it at its own
logger); each run gets its own callback struct whose `componentEnvironment` is the key of its sink.
Messages of an environment without a sink (fmpy's defaults) are printed as fmpy prints them.
"""
from __future__ import annotations

import ctypes
from collections.abc import Callable
from itertools import count

from fmpy import calloc, free
from fmpy.fmi1 import printLogMessage
from fmpy.fmi2 import (fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE, fmi2CallbackFunctions,
                       fmi2CallbackLoggerTYPE)
from fmpy.logging import addLoggerProxy

#: (environment, status, category, message) -> None, as fmi3's logMessage callback.
Sink = Callable[[object, int, bytes, bytes], None]

_SINKS: dict[int, Sink] = {}
_KEYS = count(1)


def _dispatch(environment, instance_name: bytes, status: int, category: bytes, message: bytes) -> None:
    """The logger the proxy forwards every formatted FMI 2 message to."""
    sink = _SINKS.get(environment or 0)
    if sink is None:
        printLogMessage(environment, instance_name, status, category, message)
    else:
        sink(environment, status, category, message)


_DISPATCH = fmi2CallbackLoggerTYPE(_dispatch)   # module lifetime: the proxy's static pointer targets it


def _proxy_logger():
    """Point the proxy's static pointer at _DISPATCH (again: anyone's addLoggerProxy, e.g. fmpy's
    simulate_fmu, overwrites it) and return the proxy's formatting logger."""
    functions = fmi2CallbackFunctions()
    functions.logger = _DISPATCH
    addLoggerProxy(ctypes.byref(functions))
    return functions.logger


def callbacks_for(sink: Sink) -> tuple[fmi2CallbackFunctions, int]:
    """(fmi2 callbacks whose log messages reach `sink`, key to pass to `release`); call it right
    before instantiating, so that the proxy forwards to _DISPATCH."""
    key = next(_KEYS)
    _SINKS[key] = sink
    functions = fmi2CallbackFunctions()
    functions.logger = _proxy_logger()
    functions.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
    functions.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
    functions.componentEnvironment = key
    return functions, key


def release(key: int) -> None:
    """Forget the sink of `key` (its FMU instance has been freed)."""
    _SINKS.pop(key, None)

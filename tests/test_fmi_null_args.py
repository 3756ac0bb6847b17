"""NULL arguments to the FMI functions return Error with a logged message instead of crashing
(issue 16, item 3).

Each call goes straight through ctypes to the built FMU's binary (the same one `imufmu run`
loads), on an initialised instance in Step Mode, in a forked child process: a segmentation fault
there is a failed test, not a crashed test run.
"""
from __future__ import annotations

import ctypes
import multiprocessing
from ctypes import POINTER, byref, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p

import pytest

from contract.variables import by_name
from fmu.cosim import initialised_fmu

ERROR = 3                   # fmi2Error / fmi3Error
CHILD_TIMEOUT_S = 60        # generous: one case takes about 0.1 s


def _function(dll, name: str, *argtypes):
    """The FMI function `name` of the loaded binary, returning the status (int)."""
    f = getattr(dll, name)
    f.argtypes = list(argtypes)
    f.restype = c_int
    return f


def _state(dll, c, prefix: str) -> tuple[c_void_p, int]:
    """A state of instance c (FMUstate / FMUState per prefix) and its serialised size [bytes]."""
    state, size = c_void_p(), c_size_t()
    assert _function(dll, f"{prefix}GetFMU{'state' if prefix == 'fmi2' else 'State'}", c_void_p, c_void_p)(c, byref(state)) == 0
    size_name = "fmi2SerializedFMUstateSize" if prefix == "fmi2" else "fmi3SerializedFMUStateSize"
    assert _function(dll, size_name, c_void_p, c_void_p, c_void_p)(c, state, byref(size)) == 0
    return state, size.value


def _vr(name: str) -> c_uint:
    """The value reference of variable `name`."""
    return c_uint(by_name(name).value_reference)


def _one(ctype):
    """A one-element array of ctype."""
    return (ctype * 1)()


#: (name, FMI version, call(dll, component) -> status, word the logged message must contain)
CASES = [
    ("fmi2GetFMUstate(c, NULL)", 2,
     lambda d, c: _function(d, "fmi2GetFMUstate", c_void_p, c_void_p)(c, None), "FMUstate pointer"),
    ("fmi2SerializedFMUstateSize(c, s, NULL)", 2,
     lambda d, c: _function(d, "fmi2SerializedFMUstateSize", c_void_p, c_void_p, c_void_p)(
         c, _state(d, c, "fmi2")[0], None), "size pointer"),
    ("fmi2SerializeFMUstate(c, s, NULL, size)", 2,
     lambda d, c: _serialise_into_null(d, c, "fmi2", "fmi2SerializeFMUstate"), "serializedState buffer"),
    ("fmi2DeSerializeFMUstate(c, NULL, size, &s)", 2,
     lambda d, c: _function(d, "fmi2DeSerializeFMUstate", c_void_p, c_void_p, c_size_t, c_void_p)(
         c, None, _state(d, c, "fmi2")[1], byref(c_void_p())), "fmi2DeSerializeFMUstate"),
    ("fmi2DeSerializeFMUstate(c, bytes, size, NULL)", 2,
     lambda d, c: _serialised_then(d, c, "fmi2", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate"), "FMUstate pointer"),
    ("fmi2SetDebugLogging(c, 1, 2, NULL)", 2,
     lambda d, c: _function(d, "fmi2SetDebugLogging", c_void_p, c_int, c_size_t, c_void_p)(c, 1, 2, None), "NULL"),
    ("fmi2SetDebugLogging(c, 1, 2, {logEvents, NULL})", 2,
     lambda d, c: _function(d, "fmi2SetDebugLogging", c_void_p, c_int, c_size_t, POINTER(c_char_p))(
         c, 1, 2, (c_char_p * 2)(b"logEvents", None)), "category 1"),
    ("fmi2GetReal(c, NULL, 1, values)", 2,
     lambda d, c: _function(d, "fmi2GetReal", c_void_p, c_void_p, c_size_t, c_void_p)(c, None, 1, _one(c_double)),
     "value reference array"),
    ("fmi2GetReal(c, vr, 1, NULL)", 2,
     lambda d, c: _function(d, "fmi2GetReal", c_void_p, c_void_p, c_size_t, c_void_p)(c, byref(_vr("roll")), 1, None),
     "value array"),
    ("fmi2SetReal(c, vr, 1, NULL)", 2,
     lambda d, c: _function(d, "fmi2SetReal", c_void_p, c_void_p, c_size_t, c_void_p)(c, byref(_vr("gyr_x")), 1, None),
     "value array"),
    ("fmi2GetBoolean(c, vr, 1, NULL)", 2,
     lambda d, c: _function(d, "fmi2GetBoolean", c_void_p, c_void_p, c_size_t, c_void_p)(
         c, byref(_vr("enable_pf")), 1, None),
     "value array"),
    ("fmi2GetString(c, NULL, 1, NULL)", 2,
     lambda d, c: _function(d, "fmi2GetString", c_void_p, c_void_p, c_size_t, c_void_p)(c, None, 1, None),
     "value reference array"),
    ("fmi2GetRealStatus(c, fmi2LastSuccessfulTime, NULL)", 2,
     lambda d, c: _function(d, "fmi2GetRealStatus", c_void_p, c_int, c_void_p)(c, 2, None), "value pointer"),
    ("fmi3GetFMUState(c, NULL)", 3,
     lambda d, c: _function(d, "fmi3GetFMUState", c_void_p, c_void_p)(c, None), "FMUState pointer"),
    ("fmi3SerializedFMUStateSize(c, s, NULL)", 3,
     lambda d, c: _function(d, "fmi3SerializedFMUStateSize", c_void_p, c_void_p, c_void_p)(
         c, _state(d, c, "fmi3")[0], None), "size pointer"),
    ("fmi3SerializeFMUState(c, s, NULL, size)", 3,
     lambda d, c: _serialise_into_null(d, c, "fmi3", "fmi3SerializeFMUState"), "serializedState buffer"),
    ("fmi3DeserializeFMUState(c, bytes, size, NULL)", 3,
     lambda d, c: _serialised_then(d, c, "fmi3", "fmi3SerializeFMUState", "fmi3DeserializeFMUState"), "FMUState pointer"),
    ("fmi3SetDebugLogging(c, 1, 2, NULL)", 3,
     lambda d, c: _function(d, "fmi3SetDebugLogging", c_void_p, c_int, c_size_t, c_void_p)(c, 1, 2, None), "NULL"),
    ("fmi3SetDebugLogging(c, 1, 2, {logEvents, NULL})", 3,
     lambda d, c: _function(d, "fmi3SetDebugLogging", c_void_p, c_int, c_size_t, POINTER(c_char_p))(
         c, 1, 2, (c_char_p * 2)(b"logEvents", None)), "category 1"),
    ("fmi3GetFloat64(c, NULL, 1, values, 1)", 3,
     lambda d, c: _function(d, "fmi3GetFloat64", c_void_p, c_void_p, c_size_t, c_void_p, c_size_t)(
         c, None, 1, _one(c_double), 1), "value reference array"),
    ("fmi3GetFloat64(c, vr, 1, NULL, 1)", 3,
     lambda d, c: _function(d, "fmi3GetFloat64", c_void_p, c_void_p, c_size_t, c_void_p, c_size_t)(
         c, byref(_vr("roll")), 1, None, 1), "value array"),
    ("fmi3SetFloat64(c, vr, 1, NULL, 1)", 3,
     lambda d, c: _function(d, "fmi3SetFloat64", c_void_p, c_void_p, c_size_t, c_void_p, c_size_t)(
         c, byref(_vr("gyr_x")), 1, None, 1), "value array"),
    ("fmi3GetUInt64(c, NULL, 1, NULL, 1)", 3,
     lambda d, c: _function(d, "fmi3GetUInt64", c_void_p, c_void_p, c_size_t, c_void_p, c_size_t)(
         c, None, 1, None, 1), "value reference array"),
    ("fmi3DoStep(c, t, h, 0, NULL, NULL, NULL, NULL)", 3,
     lambda d, c: _function(d, "fmi3DoStep", c_void_p, c_double, c_double, c_int, c_void_p, c_void_p, c_void_p, c_void_p)(
         c, 0.0, 0.01, 0, None, None, None, None), "eventHandlingNeeded"),
    ("fmi3DoStep(c, t, h, 0, &b, &b, &b, NULL)", 3,
     lambda d, c: _function(d, "fmi3DoStep", c_void_p, c_double, c_double, c_int, c_void_p, c_void_p, c_void_p, c_void_p)(
         c, 0.0, 0.01, 0, byref(ctypes.c_bool()), byref(ctypes.c_bool()), byref(ctypes.c_bool()), None),
     "lastSuccessfulTime"),
]


def _serialise_into_null(dll, c, prefix: str, serialise: str) -> int:
    """Serialise a state of c into a NULL buffer of the right size."""
    state, size = _state(dll, c, prefix)
    return _function(dll, serialise, c_void_p, c_void_p, c_void_p, c_size_t)(c, state, None, size)


def _serialised_then(dll, c, prefix: str, serialise: str, deserialise: str) -> int:
    """Serialise a state of c correctly, then deserialise the bytes into a NULL FMUstate pointer."""
    state, size = _state(dll, c, prefix)
    buffer = (ctypes.c_char * size)()
    assert _function(dll, serialise, c_void_p, c_void_p, c_void_p, c_size_t)(c, state, buffer, size) == 0
    return _function(dll, deserialise, c_void_p, c_void_p, c_size_t, c_void_p)(c, buffer, size, None)


def _child(fmu_path, index: int, pipe) -> None:
    """In the child: initialise the FMU, make call `index` and send (status, new log messages)."""
    with initialised_fmu(fmu_path) as fmu:
        before = len(fmu.log_messages)
        status = CASES[index][2](fmu.dll, fmu.component)
        pipe.send((status, fmu.log_messages[before:]))


@pytest.mark.parametrize("index", range(len(CASES)), ids=[case[0] for case in CASES])
def test_null_argument_is_an_error_with_a_message_not_a_crash(request, index):
    name, version, _, word = CASES[index]
    fmu_path = request.getfixturevalue(f"identity_fmu{version}")
    context = multiprocessing.get_context("fork")
    receive, send = context.Pipe(duplex=False)
    child = context.Process(target=_child, args=(fmu_path, index, send))
    child.start()
    child.join(CHILD_TIMEOUT_S)
    assert child.exitcode == 0, f"{name}: the child process ended with {child.exitcode} (negative: killed by that signal)"
    status, messages = receive.recv()
    assert status == ERROR, f"{name} returned {status}, not Error"
    assert any(word in m and "[ERROR]" in m for m in messages), f"{name} logged {messages}"

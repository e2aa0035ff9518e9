"""A host process that feeds fuzzed FMU states to an FMU (run by tests/test_fmu_fuzz.py).

    python state_fuzz_host.py FMU_DIR SEED COUNT WATCHDOG_S [CPU_S]

The FMU (extracted in FMU_DIR) is stepped to a state with some history, which is serialised.
Then COUNT fuzzed byte strings, of three kinds in turn, are deserialised, and each accepted
state is set and stepped:

* ``flip``: 1 to 8 random bytes of the valid serialisation flipped (any bits);
* ``field``: one field changed to an adversarial value, the result a well-formed state (what a
  checksum recomputed after the corruption would let through): a JSON body is decoded, one
  value anywhere in it replaced and encoded again; a binary body gets one aligned 4- or 8-byte
  word replaced by an adversarial int32, int64 or double;
* ``random``: random bytes, of the valid length or another.

Before each state a watchdog (``faulthandler``) is armed for WATCHDOG_S seconds: a state that
hangs the FMU ends this process with a traceback, a crash ends it with a signal; the parent
sees either.  With CPU_S (whole seconds), the process's CPU time is limited too (RLIMIT_CPU, reset
before each state to what is used plus CPU_S + 1): a state that computes for more than CPU_S to
CPU_S + 1 s of CPU ends the process with SIGXCPU, however loaded the machine (the wall-clock
watchdog can then be generous: a loaded host stretches wall time, not CPU time).  Each state prints ``<index> <kind> <outcome>`` (``refused``, ``ran``, ``failed``:
accepted, then a step refused) as soon as it is done; the last line is a JSON summary.  An
accepted state whose outputs leave the declared ranges (Reals finite and within min/max, the
counters >= 0, the mode among its values) prints ``bad <index> <kind> <what>`` and exits 3.
"""
from __future__ import annotations

import faulthandler
import json
import math
import resource
import struct
import sys
from pathlib import Path

import numpy as np
from fmpy.fmi1 import FMICallException

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fmu_slave import Slave  # noqa: E402

#: the front's header before the model's body: magic, GUID, instance state, pad, two times
FRONT_HEADER = 8 + 64 + 4 + 4 + 8 + 8
KINDS = ("flip", "field", "random")
ADVERSARIAL_INTS = (-1, -2, -(2 ** 31), 2 ** 31 - 1, 2 ** 63 - 1, -(2 ** 63), 3, 7, 1000, 2 ** 53)
ADVERSARIAL_REALS = (math.nan, math.inf, -math.inf, 1e308, -1e308, 1e300, -1e12, 1e12, 1e9 + 1, -1e9 - 1,
                     5e-324, -0.0, 0.0, 1e-300, 1.0, -1.0, 2.0, 0.5)
JSON_VALUES = ADVERSARIAL_INTS + ADVERSARIAL_REALS + (None, True, False, "x", [], {}, [1.0], 10 ** 400)
#: steps after an accepted state, each of the default experiment's step size
N_STEPS = 3


def _leaves(obj, path=()):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _leaves(v, path + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _leaves(v, path + (i,))
    yield path


def _replace(obj, path, value):
    if not path:
        return value
    obj[path[0]] = _replace(obj[path[0]], path[1:], value)
    return obj


def corrupt_field(data: bytes, rng) -> bytes:
    """One field of a valid serialisation changed, the result well formed."""
    header, body = bytearray(data[:FRONT_HEADER]), data[FRONT_HEADER:]
    if rng.random() < 0.1:      # a field of the front's header: instance state or a time
        off = int(rng.choice([72, 80, 88]))
        if off == 72:
            header[off:off + 4] = struct.pack("<i", int(rng.choice([0, 1, 2, 3, 5, 16, 64, 128, -1, 2 ** 30])))
        else:
            header[off:off + 8] = struct.pack("<d", float(rng.choice(ADVERSARIAL_REALS)))
        return bytes(header) + body
    try:
        doc = json.loads(body.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        doc = None
    if isinstance(doc, dict):
        leaves = list(_leaves(doc))
        path = leaves[int(rng.integers(len(leaves)))]
        value = JSON_VALUES[int(rng.integers(len(JSON_VALUES)))]
        doc = _replace(doc, path, value)
        return bytes(header) + json.dumps(doc).encode("utf-8")
    body = bytearray(body)
    width = 8 if rng.random() < 0.6 else 4
    off = int(rng.integers(len(body) // width)) * width
    if width == 8 and rng.random() < 0.5:
        # half of the 8-byte words from those holding a small int64 (modes, indexes, counters; a
        # double 0.0 reads as 0 too): the fields whose range checks guard the kernel's memory
        small = [o for o in range(0, len(body) - 7, 8) if -1 <= struct.unpack_from("<q", body, o)[0] < 2 ** 20]
        if small:
            off = small[int(rng.integers(len(small)))]
    if width == 4:
        word = struct.pack("<i", int(rng.choice([v for v in ADVERSARIAL_INTS if -(2 ** 31) <= v < 2 ** 31])))
    elif rng.random() < 0.5:
        word = struct.pack("<q", int(rng.choice([v for v in ADVERSARIAL_INTS if -(2 ** 63) <= v < 2 ** 63])))
    else:
        word = struct.pack("<d", float(rng.choice(ADVERSARIAL_REALS)))
    body[off:off + width] = word
    return bytes(header) + bytes(body)


def fuzzed(kind: str, valid: bytes, rng) -> bytes:
    if kind == "flip":
        b = bytearray(valid)
        for _ in range(int(rng.integers(1, 9))):
            i = int(rng.integers(len(b)))
            b[i] ^= int(rng.integers(1, 256))
        return bytes(b)
    if kind == "field":
        return corrupt_field(valid, rng)
    n = len(valid) if rng.random() < 0.5 else int(rng.integers(0, 2 * len(valid) + 1))
    b = bytearray(rng.integers(0, 256, size=n, dtype=np.uint8).tobytes())
    if rng.random() < 0.5:          # past the front's header more often than by chance
        b[:min(n, FRONT_HEADER)] = valid[:min(n, FRONT_HEADER)]
    return bytes(b)


class Checker:
    """The declared ranges of the FMU's outputs."""

    def __init__(self, s: Slave):
        self.reals, self.ints = [], []
        for v in s.md.modelVariables:
            if v.causality != "output":
                continue
            if v.type in ("Real", "Float64"):
                lo = float(v.min) if v.min is not None else -math.inf
                hi = float(v.max) if v.max is not None else math.inf
                self.reals.append((v.name, v.valueReference, lo, hi))
            elif v.type in ("Integer", "Int32", "UInt64"):
                allowed = {0, 1} if v.name == "stick_slip" else None
                self.ints.append((v.name, v.valueReference, allowed))

    def problem(self, s: Slave):
        values = s.fmu.getReal([vr for _, vr, _, _ in self.reals])
        for (name, _, lo, hi), x in zip(self.reals, values):
            if not (math.isfinite(x) and lo <= x <= hi):
                return f"{name} = {x!r} outside [{lo}, {hi}]"
        if self.ints:
            values = s.fmu.getInteger([vr for _, vr, _ in self.ints])
            for (name, _, allowed), k in zip(self.ints, values):
                if k < 0 or (allowed is not None and k not in allowed):
                    return f"{name} = {k!r} out of range"
        return None


def _prepare(fmu_dir: Path) -> tuple:
    """An instance stepped into a state with some history, and that state's bytes."""
    s = Slave(fmu_dir)
    inputs = [n for n in ("hammer_position", "hammer_velocity") if n in s.vr and
              next(v for v in s.md.modelVariables if v.name == n).causality == "input"]
    rest = s.get("hammer_position_at_rest")[0] if "hammer_position_at_rest" in s.vr else 0.0
    for i in range(60):
        if inputs:        # the string: the hammer moving about its rest position
            u = 25.0 * i * 1e-3
            ph = u - int(u)
            s.fmu.setReal([s.vr["hammer_position"], s.vr["hammer_velocity"]],
                          [rest + 2e-4 * ph * (1 - ph), 5e-3 * (1 - 2 * ph)])
        s.step()
    if not s.md.coSimulation.canGetAndSetFMUstate:
        # no states declared (every state call is refused): a well-formed front header, a body of
        # the variables' values as JSON stands in for a valid serialisation
        header = b"HBFMU01\0" + s.md.guid.encode().ljust(64, b"\0") + struct.pack("<iidd", 4, 0, s.t, s.t)
        body = json.dumps({v.name: 0.0 for v in s.md.modelVariables}).encode()
        return s, None, header + body
    state = s.fmu.getFMUstate()
    return s, state, bytes(s.fmu.serializeFMUstate(state))


def main(argv) -> int:
    fmu_dir, seed, count, watchdog = Path(argv[1]), int(argv[2]), int(argv[3]), float(argv[4])
    cpu_budget = int(argv[5]) if len(argv) > 5 else None
    rng = np.random.default_rng(seed)
    s, base, valid = _prepare(fmu_dir)
    check = Checker(s)
    t_base = s.t
    counts = {f"{k}:{o}": 0 for k in KINDS for o in ("refused", "ran", "failed")}
    for i in range(count):
        kind = KINDS[i % len(KINDS)]
        data = fuzzed(kind, valid, rng)
        faulthandler.dump_traceback_later(watchdog, exit=True)
        if cpu_budget is not None:
            _limit_cpu(cpu_budget)
        outcome = "ran"
        try:
            state = s.fmu.deSerializeFMUstate(data)
        except FMICallException:
            outcome = "refused"
        if outcome != "refused":
            try:
                s.fmu.setFMUstate(state)
            except FMICallException:
                outcome = "refused"
            s.fmu.freeFMUstate(state)
        if outcome == "ran":
            try:
                now = _state_time(data)
                h = s.md.defaultExperiment.stepSize
                h = float(h) if h else 1e-3
                for _ in range(N_STEPS):
                    s.fmu.doStep(now, h)
                    now += h
            except FMICallException:
                outcome = "failed"
            why = check.problem(s)
            if why:
                print(f"bad {i} {kind} {why}", flush=True)
                return 3
        faulthandler.cancel_dump_traceback_later()
        counts[f"{kind}:{outcome}"] += 1
        print(f"{i} {kind} {outcome}", flush=True)
        try:
            if base is not None:
                s.fmu.setFMUstate(base)      # back to the valid state (also out of the Error state)
            else:
                s.fmu.reset()                # out of the Error state: a fresh instance
                s.fmu.setupExperiment(startTime=0.0)
                s.fmu.enterInitializationMode()
                s.fmu.exitInitializationMode()
        except FMICallException as e:        # fmi2Fatal: the instance is lost, as good as a crash
            print(f"bad {i} {kind} the instance cannot go back to a valid state ({e}): "
                  f"{s.messages[-2:]}", flush=True)
            return 3
        s.t = t_base
    print(json.dumps(counts), flush=True)
    return 0


def _limit_cpu(budget: int) -> None:
    """SIGXCPU once this process has computed ``budget`` to ``budget + 1`` s more (the limit counts
    whole seconds)."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    used = usage.ru_utime + usage.ru_stime
    resource.setrlimit(resource.RLIMIT_CPU, (int(used) + 1 + budget, resource.RLIM_INFINITY))


def _state_time(data: bytes) -> float:
    """The communication time a state's front header holds (where the next step starts)."""
    return struct.unpack("<d", data[80:88])[0]


if __name__ == "__main__":
    sys.exit(main(sys.argv))

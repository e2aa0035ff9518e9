"""Reading and setting the HammerBitRock FMU's variables: the fmi2Get*/fmi2Set* calls, all or nothing.

A mixin of :class:`~.slave.HammerBitRock`: every call records the FMI status it
should return in ``last_status`` and logs each refusal with the variable's name,
its value and the allowed range; a refused value changes nothing.
"""
from __future__ import annotations

import math

from pythonfmu import Boolean, Integer, Real

from .fmu_variable_xml import KIND_NAME
from .fmu_variables import FIXED_REALS, INPUTS, range_key
from .validation import ParameterError, check
from .fmi_status import ERROR, OK, WARNING

_isfinite = math.isfinite


class VariableAccess:
    """fmi2Get*/fmi2Set* and the setters of inputs and parameters."""

    # ------------------------------------------------------------------
    # fmi2Get*/fmi2Set*: dictionary lookups; never raise into the C wrapper
    # ------------------------------------------------------------------
    def _bad_reference(self, what, vrs, kind) -> str:
        bad = []
        for vr in vrs:
            entry = self._names.get(vr) if isinstance(vr, int) else None
            if entry is None:
                bad.append(f"{vr!r} (no such variable)")
            elif entry[1] is not kind:
                bad.append(f"{vr} ({entry[0]!r} is {KIND_NAME[entry[1]]}, not {KIND_NAME[kind]})")
            elif what.startswith("fmi2Set") and vr not in self._setters[kind]:
                bad.append(f"{vr} ({entry[0]!r} is not settable: an output or a local variable)")
        return f"{what}: invalid value reference {', '.join(bad)}; nothing changed"

    def _get(self, kind, conv, vrs, what, fill):
        if self._stale:
            self._refresh_initial_outputs()
        g = self._getters[kind]
        try:
            return [conv(g[vr]()) for vr in vrs]
        except KeyError:
            self._fail(self._bad_reference(what, vrs, kind))
            return [fill] * len(vrs)

    def get_real(self, vrs):
        if self._stale:
            self._refresh_initial_outputs()
        g = self._real_get
        try:
            if len(vrs) == 1:
                return [g[vrs[0]]()]
            return [g[vr]() for vr in vrs]     # getters return numbers; the wrapper converts
        except KeyError:
            self._fail(self._bad_reference("fmi2GetReal", vrs, Real))
            return [math.nan] * len(vrs)

    def get_integer(self, vrs):
        return self._get(Integer, int, vrs, "fmi2GetInteger", 0)

    def get_boolean(self, vrs):
        return self._get(Boolean, bool, vrs, "fmi2GetBoolean", False)

    def get_string(self, vrs):
        self._fail(f"fmi2GetString: invalid value references {list(vrs)!r} (the model has no String "
                   f"variables)")
        return [""] * len(vrs)

    def _set(self, kind, vrs, values, what):
        s = self._setters[kind]
        try:
            setters = [s[vr] for vr in vrs]
        except KeyError:
            return self._fail(self._bad_reference(what, vrs, kind))
        # all or nothing: a refused value puts back the ones set before it
        names = [self._names[vr][0] for vr in vrs]
        saved = {n: getattr(self, n) for n in names}
        flags = (self._dirty, self._slow, self._stale)
        status = OK
        for f, v in zip(setters, values):
            status = max(status, f(v))
            if status >= ERROR:
                break
        if status >= ERROR:
            for n, v in saved.items():
                setattr(self, n, v)
            self._dirty, self._slow, self._stale = flags
            if len(vrs) > 1:
                self._fail(f"{what}: one of the {len(vrs)} values was refused, so none of them was "
                           f"applied")
        self.last_status = status

    def set_real(self, vrs, values):
        if len(vrs) == 1:
            f = self._real_set.get(vrs[0])
            if f is not None:
                self.last_status = f(values[0])
                return
        self._set(Real, vrs, values, "fmi2SetReal")

    def set_integer(self, vrs, values):
        self._set(Integer, vrs, values, "fmi2SetInteger")

    def set_boolean(self, vrs, values):
        self._set(Boolean, vrs, values, "fmi2SetBoolean")

    def set_string(self, vrs, values):
        self._fail(f"fmi2SetString: invalid value references {list(vrs)!r} (the model has no String "
                   f"variables); nothing changed")

    # ------------------------------------------------------------------
    # setters of inputs and parameters (return the FMI status)
    # ------------------------------------------------------------------
    def _input_setter(self, name):
        d = self.__dict__
        ranges = self._input_ranges

        def setter(value):
            rng = ranges[name]
            if rng.lo <= value <= rng.hi:               # False for NaN
                d[name] = value
                return OK
            if not self._ready and _isfinite(value):
                # before initialisation the range follows parameters that may still change (in
                # this very call): exit_initialization_mode checks it for the parameters it commits
                d[name] = value
                return OK
            self._fail(f"input {name!r} = {value!r} is out of range: allowed {rng.text()} "
                       f"(1000 F0, F0 = mu_static normal_force = {self._F0!r} N, the static friction "
                       f"threshold); refused, {d[name]!r} N stays")
            return ERROR
        return setter

    def _check_inputs(self) -> None:
        """ParameterError if an input is outside its range for the parameters in use."""
        for name in (i.name for i in INPUTS):
            rng = self._input_ranges[name]
            value = getattr(self, name)
            if not rng.lo <= value <= rng.hi:
                raise ParameterError(name, value, f"{rng.text()} (1000 F0 for the parameters in use, "
                                                  f"F0 = {self._F0!r} N)")

    def _param_setter(self, name):
        is_bool = name == "impact_enabled"

        def setter(value):
            if self._ready:
                return self._set_after_initialisation(name, value)
            setattr(self, name, bool(value) if is_bool else value)
            self._stale = True
            if is_bool:
                return OK
            try:
                check(range_key(name), value, label=name)
            except ParameterError as e:        # an error only if still so at initialisation
                self._fail(f"{e}; fmi2ExitInitializationMode will fail unless it is corrected", WARNING)
                return WARNING
            return OK
        return setter

    def _set_after_initialisation(self, name, value) -> int:
        if name != "tolerance":
            self._fail(f"parameter {name!r} = {value!r} was set after initialisation, but it is fixed "
                       f"(causality=parameter, variability=fixed); refused, the value "
                       f"{self._committed[name]!r} stays in use")
            return ERROR
        try:
            check(range_key(name), value, label=name)
        except ParameterError as e:
            self._fail(f"invalid tunable {e}; refused, the tolerance {self.tolerance!r} stays in use")
            return ERROR
        self.tolerance = value
        self._dirty = True
        self._slow = True
        return OK

    def _param_values(self) -> dict:
        vals = {name: getattr(self, name) for name in FIXED_REALS}
        vals["impact_enabled"] = bool(self.impact_enabled)
        vals["tolerance"] = self.tolerance
        return vals


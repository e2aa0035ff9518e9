"""Every value reference of every FMU through every typed get and set, as FMI 2.0 and the FMU's own
modelDescription.xml say (not as the fronts are written).

For HammerBitRock, Drillstring (both flavours each) and DrillingSystem (native):

* ``fmi2Get<type>`` of its own type answers every variable, and a parameter or constant that
  nobody set reads its declared start value (section 3.2.3: initial ``exact``);
* ``fmi2Set<type>`` of its own type is accepted exactly where the footnotes of the calling-sequence
  table allow it (section 4.2.4: before initialisation a variable with initial exact or approx; in
  Initialization Mode initial exact or an input; after it a tunable parameter or an input), and the
  value set reads back, nothing else changing; everywhere else it is ``fmi2Error``;
* every other type, and a value reference the FMU does not declare, is ``fmi2Error`` (section
  2.1.7: the value references of each type are those of its variables), with no crash and every
  value as it was (read in the Error state, where section 4.2.4 allows inquiries).

The instance leaves the Error state through ``fmi2SetFMUstate`` or ``fmi2Reset`` (section 2.1.3).
"""
from __future__ import annotations

import pytest

from fmu_spec import FMI_ERROR, FMI_OK, TYPES, Instance, extract, near_value, settable, start_value

pytest.importorskip("fmpy")

FMUS = ["built_fmu", "built_native_fmu", "built_string_fmu", "built_native_string_fmu", "built_field_system_fmu"]
#: value references no FMU declares beyond its own: one past the largest, and the largest of the type
UNKNOWN_FROM_TOP = (1, 2 ** 32 - 1)
#: a value of each type, to call a setter of the wrong type with
ANY_VALUE = {"Real": 0.0, "Integer": 0, "Boolean": False, "String": "x"}


@pytest.fixture(scope="module", params=FMUS)
def fmu_dir(request, tmp_path_factory):
    return extract(request.getfixturevalue(request.param), tmp_path_factory.mktemp(request.param))


def _unknown(inst):
    top = max(v.valueReference for v in inst.vars)
    return [top + 1, UNKNOWN_FROM_TOP[1]]


class _Refusal:
    """Checks a call is fmi2Error and changes no value.  A getter may be refused in the Error state
    (section 4.2.4 allows inquiries there, so only its arguments can refuse it); before any other
    call the instance leaves the Error state, which refuses everything else."""

    def __init__(self, inst: Instance, state: str):
        self.inst, self.state = inst, state
        self.saved = inst.fmu.getFMUstate() if inst.states else None
        self.in_error = False

    def __call__(self, call, *args, what=""):
        inst = self.inst
        if self.in_error and call != inst.get:
            if self.saved is not None:
                inst.fmu.setFMUstate(self.saved)
            else:
                inst.reset()
                inst.reach(self.state)
        before = inst.values()
        n = len(inst.messages)
        assert inst.status(call, *args) == FMI_ERROR, what
        assert any(s >= FMI_ERROR for s, _ in inst.messages[n:]), f"{what}: fmi2Error without a log message"
        assert inst.values() == before, f"{what} changed a value"
        self.in_error = True

    def close(self):
        if self.saved is not None:
            self.inst.fmu.freeFMUstate(self.saved)


def test_every_variable_answers_its_own_getter_and_unset_parameters_read_their_start(fmu_dir):
    inst = Instance(fmu_dir)
    try:
        inst.to_step_complete()
        for v in inst.vars:
            assert inst.status(inst.get, v.type, [v.valueReference]) == FMI_OK, v.name
            if v.causality == "parameter" or v.variability == "constant":
                assert inst.get(v.type, [v.valueReference])[0] == start_value(v), v.name
    finally:
        inst.free()


def _wrong_types(fmu_dir, every: bool):
    """Every other type and the unknown references, through getters and setters; without
    ``every`` one refused setter of each kind (an FMU without FMU states leaves the Error state by
    a re-initialisation per call: seconds for the pythonfmu Drillstring)."""
    inst = Instance(fmu_dir)
    try:
        inst.to_step_complete()
        refused = _Refusal(inst, "stepComplete")
        sample = {(inst.vars[0].name, next(k for k in TYPES if k != inst.vars[0].type)),
                  (_unknown(inst)[0], "Real")}
        for v in inst.vars:
            for kind in TYPES:
                if kind != v.type:
                    refused(inst.get, kind, [v.valueReference], what=f"fmi2Get{kind} of {v.type} {v.name}")
                    if every or (v.name, kind) in sample:
                        refused(inst.set, kind, [v.valueReference], [ANY_VALUE[kind]],
                                what=f"fmi2Set{kind} of {v.type} {v.name}")
        for vr in _unknown(inst):
            for kind in TYPES:
                refused(inst.get, kind, [vr], what=f"fmi2Get{kind} of unknown {vr}")
                if every or (vr, kind) in sample:
                    refused(inst.set, kind, [vr], [ANY_VALUE[kind]], what=f"fmi2Set{kind} of unknown {vr}")
        refused.close()
        return inst.states
    finally:
        inst.free()


def test_every_other_type_and_every_unknown_reference_is_an_error_that_changes_nothing(fmu_dir):
    from fmpy import read_model_description
    _wrong_types(fmu_dir, every=bool(read_model_description(str(fmu_dir)).coSimulation.canGetAndSetFMUstate))


@pytest.mark.slow
def test_every_other_type_of_every_variable_of_an_fmu_without_states(fmu_dir):
    """The setters of the test above on every variable where it samples them (FMUs without states)."""
    from fmpy import read_model_description
    if read_model_description(str(fmu_dir)).coSimulation.canGetAndSetFMUstate:
        pytest.skip("covered in full by the fast test")
    _wrong_types(fmu_dir, every=True)


@pytest.mark.parametrize("state", ["instantiated", "init", "stepComplete"])
def test_each_setter_is_accepted_exactly_where_the_table_allows_it(fmu_dir, state):
    """Allowed: the value (the start before initialisation, a neighbouring legal value after it)
    reads back and no other parameter or input changes.  Not allowed: fmi2Error, nothing changed
    (compared where the state allows inquiries)."""
    inst = Instance(fmu_dir)
    try:
        inst.reach(state)
        saved = inst.fmu.getFMUstate() if inst.states else None   # allowed in every state here
        inquire = state != "instantiated"             # section 4.2.4: no fmi2Get before initialisation
        for v in inst.vars:
            ok = settable(v, state)
            value = (near_value(v) if state == "stepComplete" else start_value(v)) if ok else ANY_VALUE[v.type]
            if value is None:
                value = ANY_VALUE[v.type]
            before = inst.values() if inquire else None
            status = inst.status(inst.set, v.type, [v.valueReference], [value])
            if ok:
                assert status == FMI_OK, (v.name, state)
                if inquire:
                    after = inst.values()
                    assert inst.get(v.type, [v.valueReference])[0] == value, (v.name, state)
                    assert {k: x for k, x in after.items() if k != v.name and _held(inst, k)} == \
                        {k: x for k, x in before.items() if k != v.name and _held(inst, k)}, (v.name, state)
                continue
            assert status == FMI_ERROR, (v.name, v.causality, v.variability, v.initial, state)
            if inquire:
                assert inst.values() == before, (v.name, state)
            if saved is not None:
                inst.fmu.setFMUstate(saved)            # out of the Error state (section 2.1.3)
            else:
                inst.reset()
                inst.reach(state)
    finally:
        inst.free()


def _held(inst, name) -> bool:
    """A parameter, input or constant: a value only a setter changes (outputs follow the inputs)."""
    v = next(v for v in inst.vars if v.name == name)
    return v.causality in ("parameter", "input") or v.variability == "constant"

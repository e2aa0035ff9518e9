/* The FMI 3.0 front's values, FMU states and what its capability flags leave out (fmi3_front.h).
 *
 * Each fmi3Get and fmi3Set checks that every value reference is a variable of its FMI 3 type
 * (hb_fmi3.h, from the description) and then calls the FMI 2.0 front's function of the FMI 2 type
 * it maps to, which applies the checks and rules of FMI 2.0 (states, settability, ranges).  Two
 * kinds of Float64 variables exist in FMI 3.0 only: the independent variable time and the event
 * indicators (the kernels' localised indicators of the current modes). */
#include <limits.h>
#include <stdint.h>
#include <string.h>

#include "fmi3_front.h"

static const char *const TYPE_NAMES[HB3_NTYPES] = {"Float64", "Int32", "UInt64", "Boolean", "String"};

/* every value reference a variable of type `type`, nValues == nValueReferences, arrays given */
static int check(hb3_inst *I, const char *fn, int type, const fmi3ValueReference vr[], size_t nvr,
                 const void *values, size_t nv, int setting) {
    if (nvr && (!vr || !values)) {
        hb3_log(I, fmi3Error, "%s: valueReferences or values is NULL with nValueReferences = %zu", fn, nvr);
        return 0;
    }
    if (nv != nvr) {
        hb3_log(I, fmi3Error, "%s: nValues = %zu differs from nValueReferences = %zu (this FMU has "
                "scalar variables only)", fn, nv, nvr);
        return 0;
    }
    for (size_t k = 0; k < nvr; k++) {
        int t = vr[k] < HB3_VR_LEN ? HB3_TYPE_OF_VR[vr[k]] : -1;
        if (t < 0) {
            hb3_log(I, fmi3Error, "%s: valueReferences[%zu] = %u is not a value reference of this FMU",
                    fn, k, vr[k]);
            return 0;
        }
        if (t != type) {
            hb3_log(I, fmi3Error, "%s: valueReferences[%zu] = %u is '%s', a %s variable, not %s",
                    fn, k, vr[k], HB3_NAMES[vr[k]], TYPE_NAMES[t], TYPE_NAMES[type]);
            return 0;
        }
        if (setting && type == HB3_FLOAT64 && (vr[k] == HB3_TIME_VR || HB3_IS_INDICATOR(vr[k]))) {
            hb3_log(I, fmi3Error, "%s: '%s' (value reference %u) cannot be set", fn, HB3_NAMES[vr[k]], vr[k]);
            return 0;
        }
    }
    return 1;
}

#define CHECK(fn, type, setting)                                                         \
    do {                                                                                 \
        if (!check(I, fn, type, valueReferences, nValueReferences, values, nValues,      \
                   setting)) {                                                           \
            I->state = F3_ERROR;                                                         \
            return fmi3Error;                                                            \
        }                                                                                \
    } while (0)

static fmi2Status worse(fmi2Status a, fmi2Status b) { return a > b ? a : b; }

/* values converted in chunks through a buffer of the FMI 2 type */
#define CHUNK 64

FMI3_Export fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    BEGIN3_VALUES("fmi3GetFloat64");
    CHECK("fmi3GetFloat64", HB3_FLOAT64, 0);
    int special = 0;
    for (size_t k = 0; k < nValueReferences && !special; k++)
        special = valueReferences[k] == HB3_TIME_VR || HB3_IS_INDICATOR(valueReferences[k]);
    if (!special) return hb3_status(I, fmi2GetReal(I->c2, valueReferences, nValueReferences, values));
    double z[HB3_NZ > 0 ? HB3_NZ : 1];
    int have_z = 0;
    fmi2Status st = fmi2OK;
    for (size_t k = 0; k < nValueReferences && st < fmi2Error; k++) {
        fmi3ValueReference r = valueReferences[k];
        if (r == HB3_TIME_VR) {
            values[k] = hb3_time(I);
        } else if (HB3_IS_INDICATOR(r)) {
            if (!have_z) st = worse(st, HB3_ME(fmi2GetEventIndicators(I->c2, z, HB3_NZ)));
            have_z = 1;
            values[k] = z[r - HB3_INDICATOR_VR0];
        } else {
            st = worse(st, fmi2GetReal(I->c2, &valueReferences[k], 1, &values[k]));
        }
    }
    return hb3_status(I, st);
}

FMI3_Export fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
    BEGIN3_VALUES("fmi3SetFloat64");
    CHECK("fmi3SetFloat64", HB3_FLOAT64, 1);
    return hb3_status(I, fmi2SetReal(I->c2, valueReferences, nValueReferences, values));
}

FMI3_Export fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, fmi3Int32 values[], size_t nValues) {
    BEGIN3_VALUES("fmi3GetInt32");
    CHECK("fmi3GetInt32", HB3_INT32, 0);
    _Static_assert(sizeof(fmi3Int32) == sizeof(fmi2Integer), "fmi2Integer is 32 bits");
    return hb3_status(I, fmi2GetInteger(I->c2, valueReferences, nValueReferences, (fmi2Integer *)values));
}

FMI3_Export fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 values[], size_t nValues) {
    BEGIN3_VALUES("fmi3SetInt32");
    CHECK("fmi3SetInt32", HB3_INT32, 1);
    return hb3_status(I, fmi2SetInteger(I->c2, valueReferences, nValueReferences,
                                        (const fmi2Integer *)values));
}

FMI3_Export fmi3Status fmi3GetUInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                     size_t nValueReferences, fmi3UInt64 values[], size_t nValues) {
    BEGIN3_VALUES("fmi3GetUInt64");
    CHECK("fmi3GetUInt64", HB3_UINT64, 0);
    fmi2Integer buf[CHUNK];
    fmi2Status st = fmi2OK;
    for (size_t k0 = 0; k0 < nValueReferences && st < fmi2Error; k0 += CHUNK) {
        size_t n = nValueReferences - k0 < CHUNK ? nValueReferences - k0 : CHUNK;
        st = worse(st, fmi2GetInteger(I->c2, valueReferences + k0, n, buf));
        for (size_t k = 0; k < n; k++) values[k0 + k] = (fmi3UInt64)(uint32_t)buf[k];   /* counts >= 0 */
    }
    return hb3_status(I, st);
}

FMI3_Export fmi3Status fmi3SetUInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                     size_t nValueReferences, const fmi3UInt64 values[], size_t nValues) {
    BEGIN3_VALUES("fmi3SetUInt64");
    CHECK("fmi3SetUInt64", HB3_UINT64, 1);
    /* the UInt64 variables are outputs: the FMI 2.0 front refuses the set with its message */
    fmi2Integer buf[CHUNK];
    fmi2Status st = fmi2OK;
    for (size_t k0 = 0; k0 < nValueReferences && st < fmi2Error; k0 += CHUNK) {
        size_t n = nValueReferences - k0 < CHUNK ? nValueReferences - k0 : CHUNK;
        for (size_t k = 0; k < n; k++)
            buf[k] = values[k0 + k] > INT_MAX ? INT_MAX : (fmi2Integer)values[k0 + k];
        st = worse(st, fmi2SetInteger(I->c2, valueReferences + k0, n, buf));
    }
    return hb3_status(I, st);
}

FMI3_Export fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    BEGIN3_VALUES("fmi3GetBoolean");
    CHECK("fmi3GetBoolean", HB3_BOOLEAN, 0);
    fmi2Boolean buf[CHUNK];
    fmi2Status st = fmi2OK;
    for (size_t k0 = 0; k0 < nValueReferences && st < fmi2Error; k0 += CHUNK) {
        size_t n = nValueReferences - k0 < CHUNK ? nValueReferences - k0 : CHUNK;
        st = worse(st, fmi2GetBoolean(I->c2, valueReferences + k0, n, buf));
        for (size_t k = 0; k < n; k++) values[k0 + k] = buf[k] != 0;
    }
    return hb3_status(I, st);
}

FMI3_Export fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, const fmi3Boolean values[], size_t nValues) {
    BEGIN3_VALUES("fmi3SetBoolean");
    CHECK("fmi3SetBoolean", HB3_BOOLEAN, 1);
    fmi2Boolean buf[CHUNK];
    fmi2Status st = fmi2OK;
    for (size_t k0 = 0; k0 < nValueReferences && st < fmi2Error; k0 += CHUNK) {
        size_t n = nValueReferences - k0 < CHUNK ? nValueReferences - k0 : CHUNK;
        for (size_t k = 0; k < n; k++) buf[k] = values[k0 + k] ? fmi2True : fmi2False;
        st = worse(st, fmi2SetBoolean(I->c2, valueReferences + k0, n, buf));
    }
    return hb3_status(I, st);
}

FMI3_Export fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                     size_t nValueReferences, fmi3String values[], size_t nValues) {
    BEGIN3_VALUES("fmi3GetString");
    CHECK("fmi3GetString", HB3_STRING, 0);
    return hb3_status(I, fmi2GetString(I->c2, valueReferences, nValueReferences, values));
}

FMI3_Export fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                     size_t nValueReferences, const fmi3String values[], size_t nValues) {
    BEGIN3_VALUES("fmi3SetString");
    CHECK("fmi3SetString", HB3_STRING, 1);
    return hb3_status(I, fmi2SetString(I->c2, valueReferences, nValueReferences, values));
}

/* the types this FMU has no variables of: no value reference is one of theirs */
static fmi3Status no_such_type(hb3_inst *I, const char *fn, size_t nvr) {
    if (!nvr) return fmi3OK;
    hb3_log(I, fmi3Error, "%s: this FMU has no variables of this type", fn);
    I->state = F3_ERROR;
    return fmi3Error;
}

#define NO_TYPE(T, CT)                                                                             \
    FMI3_Export fmi3Status fmi3Get##T(fmi3Instance instance, const fmi3ValueReference vr[],        \
                                      size_t nvr, CT values[], size_t nValues) {                   \
        BEGIN3_VALUES("fmi3Get" #T);                                                               \
        (void)vr, (void)values, (void)nValues;                                                     \
        return no_such_type(I, "fmi3Get" #T, nvr);                                                 \
    }                                                                                              \
    FMI3_Export fmi3Status fmi3Set##T(fmi3Instance instance, const fmi3ValueReference vr[],        \
                                      size_t nvr, const CT values[], size_t nValues) {             \
        BEGIN3_VALUES("fmi3Set" #T);                                                               \
        (void)vr, (void)values, (void)nValues;                                                     \
        return no_such_type(I, "fmi3Set" #T, nvr);                                                 \
    }
NO_TYPE(Float32, fmi3Float32)
NO_TYPE(Int8, fmi3Int8)
NO_TYPE(UInt8, fmi3UInt8)
NO_TYPE(Int16, fmi3Int16)
NO_TYPE(UInt16, fmi3UInt16)
NO_TYPE(UInt32, fmi3UInt32)
NO_TYPE(Int64, fmi3Int64)

FMI3_Export fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                     size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    BEGIN3_VALUES("fmi3GetBinary");
    (void)vr, (void)valueSizes, (void)values, (void)nValues;
    return no_such_type(I, "fmi3GetBinary", nvr);
}

FMI3_Export fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                     const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    BEGIN3_VALUES("fmi3SetBinary");
    (void)vr, (void)valueSizes, (void)values, (void)nValues;
    return no_such_type(I, "fmi3SetBinary", nvr);
}

FMI3_Export fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    fmi3Clock values[]) {
    BEGIN3_VALUES("fmi3GetClock");
    (void)vr, (void)values;
    return no_such_type(I, "fmi3GetClock", nvr);
}

FMI3_Export fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Clock values[]) {
    BEGIN3_VALUES("fmi3SetClock");
    (void)vr, (void)values;
    return no_such_type(I, "fmi3SetClock", nvr);
}

/* ------------------------------------------------------------------------------------------ */
/* FMU states: the FMI 2.0 front's (its header, checks and the model's whole state)             */
/* ------------------------------------------------------------------------------------------ */
FMI3_Export fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    BEGIN3_VALUES("fmi3GetFMUState");
    return hb3_status(I, fmi2GetFMUstate(I->c2, (fmi2FMUstate *)FMUState));
}

FMI3_Export fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    BEGIN3_VALUES("fmi3SetFMUState");
    fmi3Status st = hb3_status(I, fmi2SetFMUstate(I->c2, FMUState));
    /* the recovery from fmi3Error: the restored state's mode (the FMI 2.0 front's, the same order) */
    if (st <= fmi3Warning && I->state == F3_ERROR) I->state = hb_front_mode(I->c2);
    return st;
}

FMI3_Export fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    BEGIN3_VALUES("fmi3FreeFMUState");
    return hb3_status(I, fmi2FreeFMUstate(I->c2, (fmi2FMUstate *)FMUState));
}

FMI3_Export fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                                  size_t *size) {
    BEGIN3_VALUES("fmi3SerializedFMUStateSize");
    return hb3_status(I, fmi2SerializedFMUstateSize(I->c2, FMUState, size));
}

FMI3_Export fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                             fmi3Byte serializedState[], size_t size) {
    BEGIN3_VALUES("fmi3SerializeFMUState");
    return hb3_status(I, fmi2SerializeFMUstate(I->c2, FMUState, (fmi2Byte *)serializedState, size));
}

FMI3_Export fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                               size_t size, fmi3FMUState *FMUState) {
    BEGIN3_VALUES("fmi3DeserializeFMUState");
    return hb3_status(I, fmi2DeSerializeFMUstate(I->c2, (const fmi2Byte *)serializedState, size,
                                                 (fmi2FMUstate *)FMUState));
}

/* ------------------------------------------------------------------------------------------ */
/* What the capability flags leave out (providesDirectionalDerivatives, ... false; no clocks)  */
/* ------------------------------------------------------------------------------------------ */
static fmi3Status not_provided(fmi3Instance instance, const char *fn) {
    hb3_inst *I = instance;
    if (!I) return fmi3Error;
    hb3_log(I, fmi3Error, "%s: not provided by this FMU (see its capability flags)", fn);
    return fmi3Error;
}
#define NOT_PROVIDED(fn) return not_provided(instance, #fn)

FMI3_Export fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference vr,
                                                           size_t *n) {
    (void)vr, (void)n;
    NOT_PROVIDED(fmi3GetNumberOfVariableDependencies);
}
FMI3_Export fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                                   size_t ei[], fmi3ValueReference independents[],
                                                   size_t eii[], fmi3DependencyKind kinds[], size_t n) {
    (void)dependent, (void)ei, (void)independents, (void)eii, (void)kinds, (void)n;
    NOT_PROVIDED(fmi3GetVariableDependencies);
}
#define DERIVATIVE_ARGS                                                                    \
    fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,          \
        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],       \
        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity
#define UNUSED_DERIVATIVE_ARGS \
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed, \
        (void)sensitivity, (void)nSensitivity
FMI3_Export fmi3Status fmi3GetDirectionalDerivative(DERIVATIVE_ARGS) {
    UNUSED_DERIVATIVE_ARGS;
    NOT_PROVIDED(fmi3GetDirectionalDerivative);
}
FMI3_Export fmi3Status fmi3GetAdjointDerivative(DERIVATIVE_ARGS) {
    UNUSED_DERIVATIVE_ARGS;
    NOT_PROVIDED(fmi3GetAdjointDerivative);
}
FMI3_Export fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    NOT_PROVIDED(fmi3EnterConfigurationMode);
}
FMI3_Export fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    NOT_PROVIDED(fmi3ExitConfigurationMode);
}
FMI3_Export fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[],
                                              size_t n, fmi3Float64 intervals[],
                                              fmi3IntervalQualifier qualifiers[]) {
    (void)vr, (void)n, (void)intervals, (void)qualifiers;
    NOT_PROVIDED(fmi3GetIntervalDecimal);
}
FMI3_Export fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[],
                                               size_t n, fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                               fmi3IntervalQualifier qualifiers[]) {
    (void)vr, (void)n, (void)counters, (void)resolutions, (void)qualifiers;
    NOT_PROVIDED(fmi3GetIntervalFraction);
}
FMI3_Export fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                           fmi3Float64 shifts[]) {
    (void)vr, (void)n, (void)shifts;
    NOT_PROVIDED(fmi3GetShiftDecimal);
}
FMI3_Export fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                            fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr, (void)n, (void)counters, (void)resolutions;
    NOT_PROVIDED(fmi3GetShiftFraction);
}
FMI3_Export fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[],
                                              size_t n, const fmi3Float64 intervals[]) {
    (void)vr, (void)n, (void)intervals;
    NOT_PROVIDED(fmi3SetIntervalDecimal);
}
FMI3_Export fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[],
                                               size_t n, const fmi3UInt64 counters[],
                                               const fmi3UInt64 resolutions[]) {
    (void)vr, (void)n, (void)counters, (void)resolutions;
    NOT_PROVIDED(fmi3SetIntervalFraction);
}
FMI3_Export fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                           const fmi3Float64 shifts[]) {
    (void)vr, (void)n, (void)shifts;
    NOT_PROVIDED(fmi3SetShiftDecimal);
}
FMI3_Export fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                            const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr, (void)n, (void)counters, (void)resolutions;
    NOT_PROVIDED(fmi3SetShiftFraction);
}
FMI3_Export fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    NOT_PROVIDED(fmi3EvaluateDiscreteStates);
}
/* the FMI 2.0 front's fmi2GetRealOutputDerivatives: the model's own where it declares them
 * (maxOutputDerivativeOrder), else refused with its message */
FMI3_Export fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[],
                                                size_t n, const fmi3Int32 orders[], fmi3Float64 values[],
                                                size_t nValues) {
    BEGIN3_VALUES("fmi3GetOutputDerivatives");
    if (!check(I, "fmi3GetOutputDerivatives", HB3_FLOAT64, vr, n, values, nValues, 0)) {
        I->state = F3_ERROR;
        return fmi3Error;
    }
    return hb3_status(I, fmi2GetRealOutputDerivatives(I->c2, vr, n, (const fmi2Integer *)orders, values));
}
FMI3_Export fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clock,
                                                  fmi3Float64 activationTime) {
    (void)clock, (void)activationTime;
    NOT_PROVIDED(fmi3ActivateModelPartition);
}

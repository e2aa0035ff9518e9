/* Status inquiries of the FMI 2.0 front, and the functions the capability flags declare
 * unsupported (answered with fmi2Error and a message). */
#include "front_internal.h"

/* -- not supported (capability flags false) ------------------------------------------------- */
EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[],
                                               size_t nu, const fmi2ValueReference z[], size_t nz,
                                               const fmi2Real dv[], fmi2Real dz[]) {
    (void)u, (void)nu, (void)z, (void)nz, (void)dv, (void)dz;
    BEGIN("fmi2GetDirectionalDerivative", M_GET);
    LOG(I, fmi2Error, "fmi2GetDirectionalDerivative is not supported "
                      "(providesDirectionalDerivative = false)");
    return settle(I, fmi2Error);
}

/* Input and output derivatives: the model's own where it declares them (canInterpolateInputs,
 * maxOutputDerivativeOrder), after the front's checks of the value references */
EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                              size_t nvr, const fmi2Integer order[],
                                              const fmi2Real value[]) {
    BEGIN("fmi2SetRealInputDerivatives", M_SET);
    if (!hb_W.SetRealInputDerivatives) {
        LOG(I, fmi2Error, "fmi2SetRealInputDerivatives is not supported (canInterpolateInputs = false)");
        return settle(I, fmi2Error);
    }
    if (nvr == 0) return fmi2OK;
    if (!check_vrs(I, "fmi2SetRealInputDerivatives", HB_REAL, vr, nvr, value, 1) || !order) {
        if (!order) LOG(I, fmi2Error, "fmi2SetRealInputDerivatives: order is NULL");
        return settle(I, fmi2Error);
    }
    return record(I, hb_W.SetRealInputDerivatives(I->w, vr, nvr, order, value));
}

EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                               size_t nvr, const fmi2Integer order[],
                                               fmi2Real value[]) {
    BEGIN("fmi2GetRealOutputDerivatives", ST_STEP_COMPLETE | ST_TERMINATED | ST_ERROR);
    if (!hb_W.GetRealOutputDerivatives) {
        LOG(I, fmi2Error, "fmi2GetRealOutputDerivatives is not supported "
                          "(maxOutputDerivativeOrder = 0)");
        return settle(I, fmi2Error);
    }
    if (nvr == 0) return fmi2OK;
    if (!check_vrs(I, "fmi2GetRealOutputDerivatives", HB_REAL, vr, nvr, value, 0) || !order) {
        if (!order) LOG(I, fmi2Error, "fmi2GetRealOutputDerivatives: order is NULL");
        return settle(I, fmi2Error);
    }
    return record(I, hb_W.GetRealOutputDerivatives(I->w, vr, nvr, order, value));
}

/* -- status inquiries ------------------------------------------------------------------------- */
static fmi2Status bad_kind(hb_inst *I, const char *fn, fmi2StatusKind s) {
    LOG(I, fmi2Discard, "%s: status kind %d is not provided (fmi2DoStep never returns fmi2Pending)",
        fn, (int)s);
    return fmi2Discard;
}

EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)value;
    BEGIN("fmi2GetStatus", M_STATUS);
    return bad_kind(I, "fmi2GetStatus", s);
}

EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    BEGIN("fmi2GetRealStatus", M_STATUS);
    if (s != fmi2LastSuccessfulTime) return bad_kind(I, "fmi2GetRealStatus", s);
    if (!value) {
        LOG(I, fmi2Error, "fmi2GetRealStatus: value is NULL");
        return settle(I, fmi2Error);
    }
    *value = I->last_successful;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)value;
    BEGIN("fmi2GetIntegerStatus", M_STATUS);
    return bad_kind(I, "fmi2GetIntegerStatus", s);
}

EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    BEGIN("fmi2GetBooleanStatus", M_STATUS);
    if (s != fmi2Terminated) return bad_kind(I, "fmi2GetBooleanStatus", s);
    if (!value) {
        LOG(I, fmi2Error, "fmi2GetBooleanStatus: value is NULL");
        return settle(I, fmi2Error);
    }
    *value = I->state == ST_TERMINATED ? fmi2True : fmi2False;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)value;
    BEGIN("fmi2GetStringStatus", M_STATUS);
    return bad_kind(I, "fmi2GetStringStatus", s);
}

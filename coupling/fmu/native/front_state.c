/* FMU states of the FMI 2.0 front: the front's own part (instance state, times) around the
 * model's state, serialized behind a header (magic, GUID) that is checked before the model sees
 * the bytes. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "front_internal.h"

/* an FMU state of the front: the front's own part, then pythonfmu's */
#define HB_STATE_MAGIC 0x48425354u /* "HBST" */
typedef struct {
    uint32_t magic;
    int state;
    double time;
    double last_successful;
    fmi2FMUstate inner;
} hb_fmustate;

typedef struct {   /* serialised header of an hb_fmustate (followed by pythonfmu's bytes) */
    char magic[8];
    char guid[64];
    int32_t state;
    int32_t pad;
    double time;
    double last_successful;
} hb_serial_header;

/* an FMU whose model description declares no states (canGetAndSetFMUstate, canSerializeFMUstate
 * false) has a slave that cannot save its whole state: every such call is refused */
static int states_supported(hb_inst *I, const char *fn, int supported) {
    if (!supported)
        LOG(I, fmi2Error, "%s: this FMU does not support FMU states (%s is false in its model "
                          "description)", fn, HB_CAN_GET_SET_STATE ? "canSerializeFMUstate"
                                                                   : "canGetAndSetFMUstate");
    return supported;
}

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    BEGIN("fmi2GetFMUstate", M_ANY_LIVE);
    if (!states_supported(I, "fmi2GetFMUstate", HB_CAN_GET_SET_STATE)) return settle(I, fmi2Error);
    if (!FMUstate) {
        LOG(I, fmi2Error, "fmi2GetFMUstate: FMUstate is NULL");
        return settle(I, fmi2Error);
    }
    hb_fmustate *s = (hb_fmustate *)*FMUstate;
    if (s && s->magic != HB_STATE_MAGIC) {
        LOG(I, fmi2Error, "fmi2GetFMUstate: *FMUstate is not a state of this FMU (pass NULL for a "
                          "new one)");
        return settle(I, fmi2Error);
    }
    int fresh = s == NULL;
    if (fresh && !(s = calloc(1, sizeof *s))) return settle(I, fmi2Error);
    fmi2FMUstate old = s->inner;   /* a state given back to be overwritten: release its old part */
    s->inner = NULL;
    fmi2Status st = hb_W.GetFMUstate(I->w, &s->inner);
    if (old) hb_W.FreeFMUstate(I->w, &old);
    if (st > fmi2Warning) {
        if (fresh) free(s);
        return settle(I, st);
    }
    s->magic = HB_STATE_MAGIC;
    s->state = I->state;
    s->time = I->time;
    s->last_successful = I->last_successful;
    *FMUstate = s;
    return st;
}

static int check_state(hb_inst *I, const char *fn, fmi2FMUstate FMUstate) {
    const hb_fmustate *s = (const hb_fmustate *)FMUstate;
    if (!s || s->magic != HB_STATE_MAGIC || !s->inner) {
        LOG(I, fmi2Error, "%s: not an FMU state of this FMU%s", fn, s ? "" : " (NULL)");
        return 0;
    }
    return 1;
}

EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    BEGIN("fmi2SetFMUstate", M_ANY_LIVE);
    if (!states_supported(I, "fmi2SetFMUstate", HB_CAN_GET_SET_STATE)) return settle(I, fmi2Error);
    if (!check_state(I, "fmi2SetFMUstate", FMUstate)) return settle(I, fmi2Error);
    hb_fmustate *s = (hb_fmustate *)FMUstate;
    fmi2Status st = slave_status(I, hb_W.SetFMUstate(I->w, s->inner));
    if (st >= fmi2Error && I->call_max < fmi2Error)
        LOG(I, st, "fmi2SetFMUstate: the model refused the state; state unchanged");
    if (st <= fmi2Warning) {
        I->state = s->state;
        I->time = s->time;
        I->last_successful = s->last_successful;
    }
    return record(I, st);
}

EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    BEGIN("fmi2FreeFMUstate", M_ANY_LIVE);
    if (!FMUstate || !*FMUstate) return fmi2OK;
    hb_fmustate *s = (hb_fmustate *)*FMUstate;
    if (s->magic != HB_STATE_MAGIC) {
        LOG(I, fmi2Error, "fmi2FreeFMUstate: not an FMU state of this FMU");
        return settle(I, fmi2Error);
    }
    fmi2Status st = s->inner ? hb_W.FreeFMUstate(I->w, &s->inner) : fmi2OK;
    s->magic = 0;
    free(s);
    *FMUstate = NULL;
    return settle(I, st);
}

EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    BEGIN("fmi2SerializedFMUstateSize", M_ANY_LIVE);
    if (!states_supported(I, "fmi2SerializedFMUstateSize", HB_CAN_SERIALIZE_STATE)) return settle(I, fmi2Error);
    if (!size || !check_state(I, "fmi2SerializedFMUstateSize", FMUstate)) {
        if (!size) LOG(I, fmi2Error, "fmi2SerializedFMUstateSize: size is NULL");
        return settle(I, fmi2Error);
    }
    size_t inner = 0;
    fmi2Status st = hb_W.SerializedFMUstateSize(I->w, ((hb_fmustate *)FMUstate)->inner, &inner);
    if (st > fmi2Warning) return settle(I, st);
    *size = sizeof(hb_serial_header) + inner;
    return st;
}

EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                        fmi2Byte serializedState[], size_t size) {
    BEGIN("fmi2SerializeFMUstate", M_ANY_LIVE);
    if (!states_supported(I, "fmi2SerializeFMUstate", HB_CAN_SERIALIZE_STATE)) return settle(I, fmi2Error);
    if (!check_state(I, "fmi2SerializeFMUstate", FMUstate)) return settle(I, fmi2Error);
    hb_fmustate *s = (hb_fmustate *)FMUstate;
    size_t inner = 0;
    fmi2Status st = hb_W.SerializedFMUstateSize(I->w, s->inner, &inner);
    if (st > fmi2Warning) return settle(I, st);
    if (!serializedState || size != sizeof(hb_serial_header) + inner) {
        LOG(I, fmi2Error, "fmi2SerializeFMUstate: size = %zu, but the state needs %zu bytes", size,
            sizeof(hb_serial_header) + inner);
        return settle(I, fmi2Error);
    }
    hb_serial_header h;
    memset(&h, 0, sizeof h);
    memcpy(h.magic, "HBFMU01", 8);
    snprintf(h.guid, sizeof h.guid, "%s", HB_GUID);
    h.state = s->state;
    h.time = s->time;
    h.last_successful = s->last_successful;
    memcpy(serializedState, &h, sizeof h);
    return settle(I, hb_W.SerializeFMUstate(I->w, s->inner, serializedState + sizeof h, inner));
}

EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                          size_t size, fmi2FMUstate *FMUstate) {
    BEGIN("fmi2DeSerializeFMUstate", M_ANY_LIVE);
    if (!states_supported(I, "fmi2DeSerializeFMUstate", HB_CAN_SERIALIZE_STATE)) return settle(I, fmi2Error);
    hb_serial_header h;
    if (!FMUstate || !serializedState || size < sizeof h) {
        LOG(I, fmi2Error, "fmi2DeSerializeFMUstate: %s", !FMUstate ? "FMUstate is NULL"
                                                         : !serializedState ? "serializedState is NULL"
                                                                            : "too few bytes for a state of this FMU");
        return settle(I, fmi2Error);
    }
    memcpy(&h, serializedState, sizeof h);
    char guid[sizeof h.guid + 1];
    memcpy(guid, h.guid, sizeof h.guid);
    guid[sizeof h.guid] = '\0';
    if (memcmp(h.magic, "HBFMU01", 8) != 0 || strcmp(guid, HB_GUID) != 0 ||
        !(h.state & M_ANY_LIVE) || (h.state & (h.state - 1))) {
        LOG(I, fmi2Error, "fmi2DeSerializeFMUstate: the bytes are not a serialized state of this "
                          "FMU (GUID %s)", HB_GUID);
        return settle(I, fmi2Error);
    }
    if (!(fabs(h.time) <= HB_TIME_LIMIT) || !(fabs(h.last_successful) <= HB_TIME_LIMIT) ||
        h.last_successful > h.time) {
        char a[32], b[32];
        LOG(I, fmi2Error, "fmi2DeSerializeFMUstate: the state's header holds the time %s s and the "
                          "last successful time %s s: both must be finite and within the FMU's "
                          "time range, the second <= the first; refused", fmt_real(a, h.time), fmt_real(b, h.last_successful));
        return settle(I, fmi2Error);
    }
    hb_fmustate *s = (hb_fmustate *)*FMUstate;
    if (s && s->magic != HB_STATE_MAGIC) {
        LOG(I, fmi2Error, "fmi2DeSerializeFMUstate: *FMUstate is not a state of this FMU");
        return settle(I, fmi2Error);
    }
    int fresh = s == NULL;
    if (fresh && !(s = calloc(1, sizeof *s))) return settle(I, fmi2Error);
    fmi2FMUstate old = s->inner;
    s->inner = NULL;
    fmi2Status st = slave_status(
        I, hb_W.DeSerializeFMUstate(I->w, serializedState + sizeof h, size - sizeof h, &s->inner));
    if (old) hb_W.FreeFMUstate(I->w, &old);
    I->last_status = st;
    if (st >= fmi2Error && I->call_max < fmi2Error)
        LOG(I, st, "fmi2DeSerializeFMUstate: the state's body (%zu bytes after the header) is not "
                   "a valid state of this model; refused", size - sizeof h);
    if (st > fmi2Warning) {
        if (fresh) free(s);
        return settle(I, st);
    }
    s->magic = HB_STATE_MAGIC;
    s->state = h.state;
    s->time = h.time;
    s->last_successful = h.last_successful;
    *FMUstate = s;
    return st;
}

"""The forces entry point the native FMUs share: the hammer's and the bit's forces as a C function."""
from __future__ import annotations

__all__ = ["forces_entry_point"]


def forces_entry_point():
    """The cfunc ``int64 (y, ist, p, out)`` writing [spring-damper, contact (CONTACT mode only),
    force on the bit, friction] / F0 of the hammer and the bit (``hb_forces``; DrillingSystem's
    ``hsys_forces``)."""
    from numba import carray, cfunc
    from numba.core.types import CPointer, float64, int64

    from hammerbit.model import kernel_forces as KF
    from hammerbit.model import kernel_layouts as KL
    f64p, i64p = CPointer(float64), CPointer(int64)
    NI, N_P = KL.N_ISTATE, KL.N_P
    spring, on_bit, contact, kinetic, overlap = (KF.spring_damper_force, KF.force_on_bit, KF.contact_force,
                                                 KF.kinetic_friction, KF.overlap)
    I_STICK, I_CONTACT, SLIP, CONTACT = KL.I_STICK, KL.I_CONTACT, KL.SLIP, KL.CONTACT

    @cfunc(int64(f64p, i64p, f64p, f64p))
    def forces(yp, ip, pp, op):
        y, ist, p, out = carray(yp, (4,)), carray(ip, (NI,)), carray(pp, (N_P,)), carray(op, (4,))
        mc = ist[I_CONTACT]
        out[0] = spring(y, p)
        out[1] = contact(overlap(y, p), y[1] - y[3], p, mc) if mc == CONTACT else 0.0
        out[2] = on_bit(y, p, mc)
        out[3] = kinetic(y[3], p) if ist[I_STICK] == SLIP else out[2]
        return 0
    return forces

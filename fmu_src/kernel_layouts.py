"""Index layouts, mode and status codes and numeric constants shared by the numba kernels.

State layout (nondimensional)::

    y = [x1, x2, x3, x4,  z[0:nz],  e[0:ne]]

``x1, x2`` hammer position and velocity, ``x3, x4`` bit position
(penetration) and velocity; ``z`` the states of an optional linear subsystem
(the drillstring of the monolithic reference) that obeys
``z' = A z + H[:, 0] x1 + H[:, 1] x2`` (``A`` in CSR form ``Ap, Ai, Ax``;
``H`` is ``sub_in``) and pushes on the hammer with
``f_link = G . z + g[0] x1 + g[1] x2`` (``sub_out``, ``link_x``); ``e`` four optional energy
accumulators (external work, damper, contact and friction dissipation).

The kernel parameter vector ``p`` is laid out by the ``P_*`` indexes.  This
module imports nothing from numba: the parameter classes and the FMU's
variables read it without loading the compiler.

Argument groups.  The kernels pass their inputs in these named tuples (numba
compiles a tuple of arrays and numbers like separate arguments; a global
tuple is a compile-time constant), under the same names in every module::

    method  = (rk_a, rk_b, rk_c, err_w, err_w3, dense_w, ns, err_kind, err_exp)
        the Runge-Kutta tableau (``tableaux.METHODS``): stage coefficients
        (n_ext, n_ext), weights (ns,), nodes (n_ext,), error weights (ns + 1,)
        of the 5th- and 3rd-order estimates, nested dense-output weights
        (nF, n_ext); the number of stages; the error-estimate kind (0: fixed
        step); the controller exponent 1 / (error order + 1)
    tableau = (rk_a, rk_b, rk_c, ns)
        the part of ``method`` a step needs (the calls made at every step pass
        fewer arguments); ``dense_w`` goes alongside where the dense output is built
    sub     = (nz, ne, Ap, Ai, Ax, sub_in, sub_out, link_x)
        the linear subsystem (nz = sub_in.shape[0], may be 0) and the size of
        the energy block (ne = 4 or 0): A in CSR form, H, G and g (see above)
    field   = (p, ms, mc, sub)
        what the vector field reads: parameters, stick/slip and contact modes
    step    = (t0, y0, h, how, interp, act, n_act)
        the current step (start, start state, length) and how a state inside
        it is evaluated (``HOW_*``: its dense coefficients ``interp``, a re-step
        or the stick solution's constants in ``interp``); the integrated components
    scratch = (stages2, ytmp, ys, fs)
        work arrays: stages of a re-step, a stage state, a state and its rate
    rec     = (poin, samp_t, samp, log)
        the record buffers: Poincaré rows, requested sample times and their
        rows, the event log (see ``kernel_driver.advance``)
"""
# kernel parameter vector p
P_RHO = 0      # mass ratio m2/m1
P_XI = 1       # damping ratio
P_ETA = 2      # forcing frequency ratio
P_A = 3        # harmonic amplitude / F0
P_B = 4        # preload / F0
P_R = 5        # gap / x0 (inf: no impact device)
P_MU = 6       # kinetic / static friction
P_GAMMA = 7    # friction decay gamma * x0 * Omega
P_KC = 8       # contact stiffness Kc x0^n / F0
P_N = 9        # contact exponent
P_LAM = 10     # contact damping lam x0 Omega
P_PHI = 11     # forcing phase [rad]
P_FEXT = 12    # extra constant force on the hammer / F0 (FMU input, held over a step)
P_CONTACT = 13  # 1.0 if the contact code runs, 0.0 if the gap is disabled
N_P = 14


X_HAMMER = 0      # x1, hammer position
V_HAMMER = 1      # x2, hammer velocity
X_BIT = 2         # x3, bit position (penetration)
V_BIT = 3         # x4, bit velocity
Z0 = 4            # first state of the linear subsystem (then the energy block)

# hybrid modes
STICK = 0
SLIP = 1
FREE = 0
CONTACT = 1
CLAMPED = 2

# event kinds (= watched indicators)
EV_SLIP_START = 0     # stick -> slip: drive F_d rises through the static threshold
EV_STICK = 1          # slip -> stick: v_s falls to 0 with F_d <= F_s
EV_SLIP_ON = 2        # v_s touches 0 but F_d > F_s: slip goes on
EV_IMPACT = 3         # contact onset (gap closes)
EV_SEPARATION = 4     # contact end
EV_CLAMP = 5          # Hunt–Crossley tensile clamp engages (1 + lam d' falls to 0)
EV_UNCLAMP = 6        # clamp releases
EV_BOUNCE = 7         # bounce violation starts: F_d < -F_s while stuck (rock would pull)
EV_BOUNCE_END = 8     # bounce violation ends
N_EVENT_KINDS = 9
EVENT_NAMES = ("slip_start", "stick", "slip_on", "impact", "separation",
               "clamp", "unclamp", "bounce", "bounce_end")

# integer state
I_STICK = 0       # STICK / SLIP
I_CONTACT = 1     # FREE / CONTACT / CLAMPED
I_BOUNCE = 2      # 1 while the bounce condition holds
I_WIN = 3         # index of the forcing period of the event-storm window
I_WIN_EVENTS = 4  # events counted in that window
I_POIN_NEXT = 5   # index of the next Poincaré sample
I_SAMP_NEXT = 6   # index of the next requested sample time
I_NLOG = 7        # rows written in the event log
I_STEPS = 8       # accepted steps
I_REJECTS = 9     # rejected steps
I_RHS = 10        # right-hand-side evaluations
I_COUNT0 = 11     # first of N_EVENT_KINDS event counters
I_SWIN = I_COUNT0 + N_EVENT_KINDS        # forcing period of the step-count window
I_SWIN_STEPS = I_SWIN + 1                # accepted steps counted in that window
N_ISTATE = I_SWIN_STEPS + 1

# float state
F_T = 0           # current time
F_H = 1           # proposed next step
F_PEAK = 2        # peak contact force of the current contact
F_IMPACT_V = 3    # relative velocity of the last impact
F_H_MODE = 4      # first step of each regime: stick, slip, contact (3 slots)
F_V4_PEAK = 7     # peak bit velocity of the current slip (error scale of x4)
F_X3_SLIP = 8     # bit position at the start of the current slip
F_HACC = 9        # last accepted step of the current regime (predictive controller)
F_ERRACC = 10     # its error, floored at ERRACC_FLOOR (0: no history since the last event)
F_DRIVE_MIN = 11  # lowest drive on the bit f_k + f_c so far (inf before the first call)
F_T_STICK = 12    # last time the bit was stuck: its last stick event (-1: never stuck)
F_PEAK_RUN = 13   # peak contact force of the contacts ended so far (the run's, start-up included)
N_FSTATE = 14

# options
O_RTOL = 0
O_ATOL = 1
O_HMAX = 2
O_HFIXED = 3      # > 0: fixed-step method with this step (the paper's RK4)
O_EVCAP = 4       # max events per forcing period before EventStorm
O_BISECT = 5      # time tolerance of the fixed-step bisection (paper: 1e-6)
O_MAXSTEPS = 6    # max accepted steps in one call (0: unlimited)
O_POIN_T0 = 7     # time of Poincaré sample 0
O_POIN_DT = 8     # Poincaré sampling interval (the forcing period)
O_GRAZE = 9       # extremum value above which a grazing event counts
O_STEPCAP = 10    # max accepted steps per forcing period before ST_STEP_STORM (0: none)
N_OPTS = 11

# status codes of advance()
ST_DONE = 0
ST_LOG_FULL = 1
ST_EVENT_STORM = 2
ST_STEP_TOO_SMALL = 3
ST_NONFINITE = 4
ST_MAX_STEPS = 5
ST_STEP_STORM = 6
ST_BAD_INPUT = 7      # t_end not finite or before the current time (the Stepper checks first)

# event log columns
L_T, L_KIND, L_X1, L_X2, L_X3, L_X4, L_VREL, L_PEAK = range(8)
N_LOG_COLS = 8

# sample columns: x1, x2, x3, x4, contact force, link force, stick/slip, contact mode
N_SAMPLE_COLS = 8

EPS = 2.220446049250313e-16  # double precision unit round-off (ulp of 1)
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
ERRACC_FLOOR = 1e-4  # floor of the remembered error in the predictive controller
LAYER_TARGET = 0.3   # friction-layer error norm a proposed step may reach (friction_layer_err)
#: guard added under a square root or a division that must stay finite at zero
TINY = 1e-300
#: a step shorter than this (relative to |t|, at least 1) does not resolve t: the step-size floor
TIME_RESOLUTION = 10.0 * EPS
#: a remainder of a stick chunk shorter than this (relative to |t|) joins the chunk
CHUNK_SLIVER = 1e4 * EPS
#: the step never leaves a remainder shorter than this many step-size floors
SLIVER_FLOORS = 1e3
#: exact stick chunks per forcing (or natural) period: short enough for the event
#: search on each chunk to see every extremum of the indicators
STICK_CHUNKS_PER_PERIOD = 8.0
#: bound on h omega_c of the explicit method in stiff contact (inside its stability region)
CONTACT_STABILITY_LIMIT = 1.5
#: a slipping step may pass the predicted stop of the bit by this factor (not much further,
#: where the friction law is extrapolated) ...
STOP_OVERSHOOT = 1.3
#: ... but shrinks at most by this factor at once
STOP_SHRINK_FLOOR = 1e-3
#: kinetic friction: gamma_hat v below which exp(-gamma_hat v) is continued by its Taylor
#: polynomial (a trial stage past the stop cannot blow up), and exp(-FRICTION_TAYLOR_FROM)
FRICTION_TAYLOR_FROM = -4.0
EXP_FRICTION_TAYLOR = 54.598150033144236  # = math.exp(4.0), exactly (a literal: numba folds it)
DRIVE_GATE = 1e-2    # drive_dips: the exact search runs when the Hermite minimum is this close (x |rate| h)


# how a state inside the current step is evaluated
HOW_DENSE = 0     # the adaptive method's dense output
HOW_RESTEP = 1    # a fresh step of the fixed-step method (the paper's RK4 with bisection)
HOW_STICK = 2     # the closed-form stick solution (constants in ``interp``, see stick_prepare)
